"""The ``splat`` reconstructor: collects a run's views, trains Gaussians on the training split
with their true poses, and measures them on the held-out views and against the true geometry.

Outputs (:class:`Reconstruction`): the plant's Gaussian centres as its clouds (per label, by a
vote of the labels they project onto where the true depth says they are visible); the
measurements (``metrics.json``, under ``splat``); and ``splat/``: ``splats.ply`` (the layout of
:mod:`.ply`), ``split.json``, ``loss.csv``, ``test/<frame>.png`` (truth, render, error) and,
where Rerun is installed, ``training.rrd`` (:mod:`.recording`).
"""

from __future__ import annotations

import io
import json
import sys
from collections.abc import Callable

import numpy as np
from PIL import Image

from agrisim.evaluation.views import View, as_pinhole, backproject
from agrisim.interfaces import ALL, Cloud, Reconstruction, Reconstructor
from agrisim.scene.model import LabelTable

from . import FOLDER
from .cameras import downscale_image, gsplat_camera
from .options import SplatOptions
from .ply import splat_ply
from .quality import psnr, ssim
from .recording import training_recording
from .split import split_views

#: a Gaussian counts as part of the reconstruction when at least this opaque
MIN_OPACITY = 0.1
#: a centre is visible in a view when the true depth there is within this of its own, m
VISIBLE_WITHIN = 0.01


def error_ramp(error: np.ndarray) -> np.ndarray:
    """|truth - render| (0..1, H x W) as a black-red-yellow-white ramp, 4x amplified (H x W x 3)."""
    e = np.clip(error * 4.0, 0.0, 1.0)
    return (
        np.stack([np.clip(3 * e, 0, 1), np.clip(3 * e - 1, 0, 1), np.clip(3 * e - 2, 0, 1)], -1) * 255 + 0.5
    ).astype(np.uint8)


def png(image: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG")
    return buf.getvalue()


class SplatReconstructor(Reconstructor):
    """Gaussian splatting on the run's views (see the package)."""

    def __init__(self, labels: LabelTable, options: SplatOptions | None = None) -> None:
        super().__init__(labels, options if options is not None else SplatOptions())
        self.views: list[View] = []
        self._result: Reconstruction | None = None

    def integrate(self, view: View) -> dict[str, Cloud]:
        # gsplat's pinhole rasteriser: a lens's view resampled onto the pinhole of its K
        # (OpenCV's undistortion maps), so training and held-out scores are on undistorted views
        self.views.append(as_pinhole(view))  # trained on all together at the end
        self._result = None
        return {}

    def merged(self) -> dict[str, Cloud]:
        """Nothing until trained (:meth:`result`); then the plant's Gaussian centres."""
        return dict(self._result.clouds) if self._result is not None else {}

    # ------------------------------------------------------------------------------------

    def _initial_points(self, train: list[View], rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        o = self.options
        if o.init == "random":
            centres = np.array([v.world_T_camera[:3, 3] for v in train])
            lo, hi = centres.min(axis=0), centres.max(axis=0)
            return rng.uniform(lo, hi, (o.init_points, 3)), rng.integers(0, 256, (o.init_points, 3), dtype=np.uint8)
        on_plant = round(o.init_points * o.plant_init)
        p_all, c_all = self._depth_points(
            train, lambda v: np.ones(v.images.depth.shape, bool), o.init_points - on_plant, rng
        )
        p_plant, c_plant = self._depth_points(train, lambda v: v.images.labels != 0, on_plant, rng)
        return np.concatenate([p_all, p_plant]), np.concatenate([c_all, c_plant])

    @staticmethod
    def _depth_points(
        views: list[View], mask: Callable[[View], np.ndarray], count: int, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray]:
        """``count`` points (and colours) back-projected from the true depth of the pixels in
        ``mask(view)``, drawn evenly over the views' pixels."""
        if count == 0:
            return np.zeros((0, 3)), np.zeros((0, 3), np.uint8)
        per_view = -(-4 * count // len(views))
        points, colors = [], []
        for v in views:
            p, c = backproject(v, mask(v), np.inf)
            keep = rng.choice(len(p), min(per_view, len(p)), replace=False)
            points.append(p[keep])
            colors.append(c[keep])
        p, c = np.concatenate(points), np.concatenate(colors)
        keep = rng.choice(len(p), min(count, len(p)), replace=False)
        return p[keep], c[keep]

    def _vote_labels(self, centres: np.ndarray) -> np.ndarray:
        """Label id of each centre: the most frequent label under it among the views where the
        true depth puts it on the visible surface; -1 where no view sees it."""
        votes = np.zeros((len(centres), 256), np.int32)
        for v in self.views:
            T = v.world_T_camera
            p = (centres - T[:3, 3]) @ T[:3, :3]
            cam = v.camera
            z = p[:, 2]
            front = z > 1e-6
            u = np.full(len(p), -1)
            r = np.full(len(p), -1)
            u[front] = np.rint(cam.fx * p[front, 0] / z[front] + cam.cx).astype(np.int64)
            r[front] = np.rint(cam.fy * p[front, 1] / z[front] + cam.cy).astype(np.int64)
            inside = front & (u >= 0) & (u < cam.width) & (r >= 0) & (r < cam.height)
            idx = np.flatnonzero(inside)
            depth = v.images.depth[r[idx], u[idx]]
            seen = (depth > 0) & (np.abs(depth - z[idx]) < VISIBLE_WITHIN)
            idx = idx[seen]
            np.add.at(votes, (idx, v.images.labels[r[idx], u[idx]]), 1)
        label = votes.argmax(axis=1)
        label[votes.sum(axis=1) == 0] = -1
        return label

    def _small_depth(self, depth: np.ndarray) -> np.ndarray:
        """Depth at the training resolution: the block mean where the whole block was hit, else 0."""
        k = self.options.downscale
        whole = downscale_image((depth > 0).astype(np.float32), k) == 1.0
        return np.where(whole, downscale_image(depth, k), 0.0).astype(np.float32)

    def result(self) -> Reconstruction:
        from . import train as gs  # PyTorch and gsplat: only here

        o = self.options
        frames = [v.frame for v in self.views]
        train_frames, test_frames = split_views(frames, o.test_fraction, o.seed)
        by_name = {v.frame: v for v in self.views}
        train, test = [by_name[f] for f in train_frames], [by_name[f] for f in test_frames]
        rng = np.random.default_rng(o.seed)

        def cams(views: list[View]) -> tuple[np.ndarray, np.ndarray]:
            pairs = [gsplat_camera(v.camera.K, v.world_T_camera, o.downscale) for v in views]
            return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])

        def small(image: np.ndarray) -> np.ndarray:
            return np.rint(downscale_image(image.astype(np.float32), o.downscale)).astype(np.uint8)

        viewmats, Ks = cams(train)
        centres = np.array([v.world_T_camera[:3, 3] for v in self.views])
        init_points, init_colors = self._initial_points(train, rng)
        if o.extent == "cameras":
            scene_scale = 1.1 * float(np.linalg.norm(centres - centres.mean(axis=0), axis=1).max())
        else:
            scene_scale = float(np.percentile(np.linalg.norm(init_points - centres.mean(axis=0), axis=1), 95))

        def report(step: int, total: int) -> None:
            if step == total or step % max(total // 10, 1) < 50:
                print(f"splat: step {step}/{total}", file=sys.stderr, flush=True)

        images = [small(v.images.rgb) for v in train]
        splats = gs.fit(
            images,
            viewmats,
            Ks,
            init_points,
            init_colors,
            scene_scale,
            o,
            report,
            depths=[self._small_depth(v.images.depth) for v in train] if o.depth_weight > 0 else None,
            masks=[downscale_image((v.images.labels != 0).astype(np.float32), o.downscale) for v in train]
            if o.plant_weight != 1.0
            else None,
        )

        # -- held-out views: image quality and depth --------------------------------------
        params = gs.params_from_splats(splats)
        test_viewmats, test_Ks = cams(test)
        panels: dict[str, np.ndarray] = {}  # frame -> truth | render | error
        rows = []
        depth_errors = []
        height, width = images[0].shape[:2]
        for v, vm, K in zip(test, test_viewmats, test_Ks, strict=True):
            truth = small(v.images.rgb)
            render, depth = gs.render_view(params, vm, K, width, height, o.sh_degree)
            plant = downscale_image((v.images.labels != 0).astype(np.float32), o.downscale) == 1.0
            true_depth = downscale_image(v.images.depth, o.downscale)
            reference = truth / 255.0
            rows.append(
                {
                    "frame": v.frame,
                    "psnr": psnr(reference, render),
                    "ssim": ssim(reference, render),
                    "psnr_plant": psnr(reference, render, plant) if plant.any() else None,
                    "plant_pixels": int(plant.sum()),
                }
            )
            on_plant = plant & (true_depth > 0)
            depth_errors.append(np.abs(depth[on_plant] - true_depth[on_plant]))
            shown = (render * 255 + 0.5).astype(np.uint8)
            error = error_ramp(np.abs(reference - render).mean(axis=2))
            panels[v.frame] = np.concatenate([truth, shown, error], axis=1)
        errors_mm = np.concatenate(depth_errors) * 1000.0 if depth_errors else np.zeros(0)

        # -- the plant's Gaussians against the true geometry -----------------------------------
        solid = splats.opacities >= MIN_OPACITY
        labels = np.full(len(splats.means), -1)
        labels[solid] = self._vote_labels(splats.means[solid])
        plant = labels > 0
        truth_points = np.concatenate([backproject(v, v.images.labels != 0, np.inf)[0] for v in self.views])
        if len(truth_points) > 1_000_000:
            truth_points = truth_points[rng.choice(len(truth_points), 1_000_000, replace=False)]
        sample = truth_points[rng.choice(len(truth_points), min(200_000, len(truth_points)), replace=False)]
        precision_d = gs.nearest_distances(splats.means[plant], truth_points)
        recall_d = gs.nearest_distances(sample, splats.means[plant])
        geometry = {
            "plant_gaussians": int(plant.sum()),
            "truth_points": int(len(truth_points)),
            **{
                f"precision@{t}mm": float(np.mean(precision_d <= t / 1000.0)) if len(precision_d) else 0.0
                for t in (2, 5)
            },
            **{f"recall@{t}mm": float(np.mean(recall_d <= t / 1000.0)) for t in (2, 5)},
        }

        def mean(key: str) -> float | None:
            values = [r[key] for r in rows if r[key] is not None]
            return float(np.mean(values)) if values else None

        metrics = {
            "iterations": o.iterations,
            "train_views": len(train),
            "test_views": len(test),
            "resolution": [width, height],
            "gaussians": int(len(splats.means)),
            "scene_scale_m": round(scene_scale, 4),
            "train_seconds": round(splats.seconds, 2),
            "psnr": mean("psnr"),
            "ssim": mean("ssim"),
            "psnr_plant": mean("psnr_plant"),
            "depth_error_mm": {
                "median": float(np.median(errors_mm)) if len(errors_mm) else None,
                "p90": float(np.percentile(errors_mm, 90)) if len(errors_mm) else None,
                "pixels": int(len(errors_mm)),
            },
            "geometry": geometry,
            "views": rows,
        }
        files = {f"{FOLDER}/test/{frame}.png": png(panel) for frame, panel in panels.items()}
        files[f"{FOLDER}/splats.ply"] = splat_ply(
            splats.means, splats.quats, splats.log_scales, splats.opacity_logits, splats.sh0, splats.sh_rest
        )
        split = {"seed": o.seed, "test_fraction": o.test_fraction, "train": train_frames, "test": test_frames}
        files[f"{FOLDER}/split.json"] = (json.dumps(split, indent=1) + "\n").encode()
        files[f"{FOLDER}/loss.csv"] = (
            "step,loss,gaussians\n" + "".join(f"{s},{x:.6f},{n}\n" for s, x, n in splats.loss)
        ).encode()

        colors = splats.colors
        sigma = np.exp(splats.log_scales[plant].mean(axis=1))
        rrd = training_recording(splats.loss, panels, splats.means[plant], colors[plant], sigma)
        if rrd is not None:
            files[f"{FOLDER}/training.rrd"] = rrd
        clouds = {}
        for lab in self.labels.labels:
            if lab.id != 0:
                sel = labels == lab.id
                clouds[lab.name] = Cloud(splats.means[sel].astype(np.float64), colors[sel])
        clouds[ALL] = Cloud(splats.means[plant].astype(np.float64), colors[plant])
        self._result = Reconstruction(clouds=clouds, metrics=metrics, files=files)
        return self._result

"""The mitsuba renderer: path-traced RGB, exact labels and depth (see the package).

Re-rendering a saved run (``agrisim render``) needs only :meth:`MitsubaRenderer.render_rgb`:
the exact pass (the raycast renderer's :class:`SceneTracer`, on the same Dr.Jit variant) is
built on the first full :meth:`render`.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from typing import TYPE_CHECKING

import numpy as np

from agrisim.config import RenderConfig
from agrisim.errors import ConfigError
from agrisim.interfaces import CameraModel, Frame, Renderer
from agrisim.robot.cell import Cell
from agrisim.scene.camera import view_seed
from agrisim.scene.colour import encode_srgb8
from agrisim.scene.model import Mesh, Scene

from . import denoise
from . import integrator as cutout
from .camera import CV_TO_MITSUBA, load_sensor
from .options import MitsubaOptions
from .scene import build
from .variant import use_variant

if TYPE_CHECKING:
    from agrisim.plugins.render.raycast.tracing import SceneTracer

F32 = np.float32


class MitsubaRenderer(Renderer):
    """Mitsuba 3 path tracing for RGB; labels, depth and leaf instances from the raycast
    renderer's exact pass (:class:`SceneTracer`), so they are byte for byte raycast's.

    The arms are ``scene.arms`` when the scene brings them (a saved run), else the cell's URDF
    visuals decimated to ``arm_triangles`` as raycast does; none with ``--hide-robots``."""

    def __init__(self, scene: Scene, cell: Cell | None, settings: RenderConfig, options: MitsubaOptions) -> None:
        super().__init__(scene, cell, settings, options)
        self.mi = mi = use_variant(options.variant)
        # (refused before the arms' meshes are loaded: whether any are drawn is known already)
        arms_drawn = not settings.hide_robots and (bool(scene.arms) or (cell is not None and bool(cell.arms)))
        if options.freeze == "on" and arms_drawn and not mi.variant().startswith("cuda"):
            raise ConfigError(
                "[renderer.mitsuba] freeze = 'on' needs the cuda variant where the arms are drawn: on the CPU, "
                "Embree rebuilds the arms' scene as they move and a replayed view can trace the old one (wrong "
                "pixels); set freeze = 'auto' or 'off', or hide the robots"
            )
        # The exact pass poses the arms as raycast does; the path tracer poses them rounded to
        # float32 in the link frame, as a saved scene stores them, so that a run and a
        # re-render of it (agrisim render) trace exactly the same triangles.
        self._unrounded_arms = {} if settings.hide_robots else self._load_arms(scene, cell, options)
        self._arms = {
            arm: [
                (link, Mesh(m.name, m.vertices.astype(F32), m.faces, m.materials, m.face_material, m.uvs))
                for link, m in links
            ]
            for arm, links in self._unrounded_arms.items()
        }
        self._tracer: SceneTracer | None = None
        integrator: dict = {
            "type": options.integrator,
            "max_depth": int(options.max_depth),
            "rr_depth": int(options.rr_depth),
        }
        self.denoise = denoise.wanted(options)
        # cutout_path gives the denoiser's guides in its own samples; Mitsuba's integrators need
        # a second pass (the aov integrator) for them
        self.guided = self.denoise and options.integrator == cutout.NAME
        if options.integrator == cutout.NAME:
            cutout.register()
            integrator["guide"] = self.guided
        self.aov = mi.load_dict({"type": "aov", "aovs": denoise.AOVS}) if self.denoise and not self.guided else None
        parts = build(mi, scene.meshes, scene.lights, self._arms, options, integrator)
        self.arm_parts = parts.arms
        self.mi_scene = mi.load_dict(parts.scene)
        self.params = mi.traverse(self.mi_scene)
        self._arm_key: bytes | None = None
        # One sensor per camera, moved from view to view (mi.traverse), so that a frozen render
        # sees the same objects every time and replays its recording.
        self._sensor: tuple[tuple[float, ...], object, object] | None = None
        self._frozen: dict[str, object] = {}

    @staticmethod
    def _load_arms(scene: Scene, cell: Cell | None, options: MitsubaOptions) -> dict[str, list[tuple[str, Mesh]]]:
        """The arms' link meshes: the scene's own (a saved run), else the cell's URDF visuals
        decimated as raycast decimates them."""
        if scene.arms:
            return scene.arms
        if cell is None:
            return {}
        from agrisim.plugins.render.arm_visuals import arm_link_meshes

        return {
            a.name: [(lm.link, lm.mesh) for lm in arm_link_meshes(a.urdf, options.arm_triangles)] for a in cell.arms
        }

    @property
    def tracer(self) -> SceneTracer:
        """The exact pass (on this renderer's Dr.Jit variant), built when first needed."""
        if self._tracer is None:
            from agrisim.plugins.render.raycast import RaycastOptions
            from agrisim.plugins.render.raycast.tracing import SceneTracer

            options = RaycastOptions(
                near=self.options.near, arm_triangles=self.options.arm_triangles, variant=self.options.variant
            )
            self._tracer = SceneTracer(self.scene, None, options, arms=self._unrounded_arms, apart=True)
        return self._tracer

    def arm_meshes(self) -> dict[str, list[tuple[str, Mesh]]]:
        return self._arms

    def _place_arms(self, link_poses: Mapping[str, Mapping[str, np.ndarray]]) -> None:
        """Move the arms' vertices to ``link_poses`` (arms not named there vanish: their
        triangles collapse to a point, as raycast leaves them out)."""
        if not self.arm_parts:
            return
        poses = []
        for part in self.arm_parts:
            lp = link_poses.get(part.arm)
            if lp is not None and part.link not in lp:
                raise KeyError(f"link_poses[{part.arm!r}] has no pose for link {part.link!r}")
            poses.append(np.zeros((4, 4)) if lp is None else np.asarray(lp[part.link], np.float64))
        key = np.stack(poses).tobytes()
        if key == self._arm_key:
            return
        for part, T in zip(self.arm_parts, poses, strict=True):
            v = part.vertices @ T[:3, :3].T + T[:3, 3]
            self.params[part.key] = self.mi.Float(np.ascontiguousarray(v, F32).ravel())
        self.params.update()
        self._arm_key = key

    def _placed_sensor(self, camera: CameraModel, world_T_camera: np.ndarray):  # noqa: ANN202 - Mitsuba's Sensor
        """The camera's sensor at ``world_T_camera``: built for a new camera, else moved."""
        key = (camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy, camera.distortion)
        if self._sensor is None or self._sensor[0] != key:
            sensor = load_sensor(self.mi, camera, world_T_camera, self.options.spp, self.options.sampler)
            self._sensor = (key, sensor, self.mi.traverse(sensor))
            self._frozen.clear()  # recorded with the old sensor
        # moved even when just built: its transform is then held as the replays will see it
        # (a frozen function records again when its inputs' layout changes)
        _, sensor, params = self._sensor
        params["to_world"] = self.mi.ScalarTransform4f(np.asarray(world_T_camera, np.float64) @ CV_TO_MITSUBA)
        params.update()
        return sensor

    def _render(self, name: str, sensor, seed: int, integrator=None):  # noqa: ANN001, ANN202 - Mitsuba's types
        """``mi.render`` of the scene, through a frozen function when ``freeze`` is on. The seed
        is an opaque variable either way: a literal one is folded into the kernel, so each view's
        seed would compile the path tracer anew (about 3 s on a CPU) where an opaque one reuses
        it, from memory or Dr.Jit's disk cache; the images are the same bytes."""
        import drjit as dr

        mi, o = self.mi, self.options
        opaque_seed = dr.opaque(mi.UInt32, seed)
        if o.freeze == "off" or (o.freeze == "auto" and not mi.variant().startswith("cuda")):
            return mi.render(self.mi_scene, sensor=sensor, integrator=integrator, spp=o.spp, seed=opaque_seed)
        frozen = self._frozen.get(name)
        if frozen is None:
            spp = o.spp

            def render(scene, sensor, seed):  # noqa: ANN001, ANN202
                return mi.render(scene, sensor=sensor, integrator=integrator, spp=spp, seed=seed)

            frozen = self._frozen[name] = dr.freeze(render)
        return frozen(self.mi_scene, sensor, opaque_seed)  # type: ignore[operator]

    def radiance(self, camera: CameraModel, world_T_camera: np.ndarray) -> np.ndarray:
        """Linear RGB radiance, H x W x 3 float32, of one view (arms where last placed)."""
        return self._read_back(*self._launch(camera, world_T_camera))

    def _launch(self, camera: CameraModel, world_T_camera: np.ndarray) -> tuple:
        """(image, sensor, seed) of one view: the sensor placed, the render traced or replayed;
        its kernels run when the image is evaluated."""
        sensor = self._placed_sensor(camera, world_T_camera)
        seed = view_seed(camera, world_T_camera, self.options.seed) & 0xFFFFFFFF
        return self._render("image", sensor, seed), sensor, seed

    def _read_back(self, image, sensor, seed: int) -> np.ndarray:  # noqa: ANN001 - a Dr.Jit tensor, Mitsuba's sensor
        """A rendered ``image``'s linear RGB on the host, denoised when the options say so."""
        if not self.denoise:
            return np.asarray(image, F32)[..., :3]
        # (on the GPU when the image is there and PyTorch can pass it to OIDN)
        return denoise.denoise(*self._guides(image, sensor, seed))

    def _guides(self, image, sensor, seed: int):  # noqa: ANN001, ANN202 - Dr.Jit tensors
        """(radiance, albedo and normal) of a rendered ``image``: its own channels with
        cutout_path, else the aov integrator's pass."""
        if self.guided:
            return image[..., 0:3], image[..., 3:9]
        return image[..., 0:3], self._render("guide", sensor, seed ^ 0x5A5A5A5A, self.aov)

    def render_rgb(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
    ) -> tuple[np.ndarray, np.ndarray | None]:
        self._place_arms(link_poses)
        return self._encoded(camera, self.radiance(camera, world_T_camera))

    def render_rgb_stream(
        self,
        camera: CameraModel,
        views: Iterable[tuple[np.ndarray, Mapping[str, Mapping[str, np.ndarray]]]],
    ) -> Iterator[tuple[np.ndarray, np.ndarray | None]]:
        """:meth:`render_rgb` of each view, the next view's kernels launched before this one is
        read back, denoised and encoded: on a GPU the host's part of a view overlaps the next
        one's path tracing (agrisim render at 1080p, 8 spp, on an H100: 4.20 -> 4.29-4.40 views/s,
        the same PNGs; bench/mitsuba_frame_cost.py: 3.45-3.58 -> 3.98-4.14 views/s). Moving the
        arms and the sensor for the next view is safe while this one's kernels run on a GPU:
        Dr.Jit queues both on one stream, and the new vertex buffers are new arrays. Views whose
        denoiser needs a guide pass of their own (an integrator without guide channels) are
        drawn one at a time: that pass needs the sensor where the view was."""
        if self.denoise and not self.guided:
            yield from super().render_rgb_stream(camera, views)
            return
        import drjit as dr

        # On the CPU, Embree rebuilds the moved arms' hierarchy on the host at once, under the
        # rays of kernels still running (wrong pixels, measured with freeze on): there, the
        # view before is waited for first (its kernels hold every core: nothing is lost)
        in_order = self.mi.variant().startswith("cuda")
        pending: tuple | None = None
        for world_T_camera, link_poses in views:
            if pending is not None and not in_order:
                dr.sync_thread()
            self._place_arms(link_poses)
            launched = self._launch(camera, world_T_camera)
            dr.eval(launched[0])  # launched, not waited for
            if pending is not None:
                yield self._encoded(camera, self._read_back(*pending))
            pending = launched
        if pending is not None:
            yield self._encoded(camera, self._read_back(*pending))

    def _encoded(self, camera: CameraModel, radiance: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """(sRGB, radiance kept or None) of a view's linear radiance."""
        H, W = camera.height, camera.width
        radiance = np.ascontiguousarray(radiance, F32)
        rgb = np.empty((H * W, 3), np.uint8)
        linear = radiance.reshape(-1, 3)
        encode_srgb8(
            linear.copy() if self.options.radiance else linear, rgb, self.options.exposure, self.options.tonemap
        )
        return rgb.reshape(H, W, 3), (radiance.reshape(H, W, 3) if self.options.radiance else None)

    def render(
        self,
        camera: CameraModel,
        world_T_camera: np.ndarray,
        link_poses: Mapping[str, Mapping[str, np.ndarray]],
    ) -> Frame:
        from agrisim.plugins.render.raycast.tracing import label_map

        tracer = self.tracer
        if tracer.arms:
            tracer.place_arms(link_poses, (camera, world_T_camera))
        exact = tracer.exact(
            camera, world_T_camera, seg_mode=self.settings.seg_mode, label_map=label_map(self.settings.labels)
        )
        rgb, radiance = self.render_rgb(camera, world_T_camera, link_poses)
        return Frame(
            rgb=rgb,
            labels=exact["labels"],
            depth=exact["depth"],
            instances=exact.get("instances"),
            radiance=radiance,
            plants=exact.get("plants"),
        )

    def close(self) -> None:
        if self._tracer is not None:
            self._tracer.close()
        self._frozen.clear()
        self._sensor = None
        self.params = None
        self.mi_scene = None

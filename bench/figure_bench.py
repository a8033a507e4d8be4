"""Draw a bench scanned by the gantry to ``docs/bench.png`` (the Benches guide's picture): six
plants of six species on one table under the gantry, seen from outside with the camera at one
of its viewpoints, and three of the camera's views, each above its ``plants/`` mask (a colour
a plant). Run: ``python bench/figure_bench.py [--out PNG]``."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from agrisim.config import backend_options, build_config
from agrisim.episode import Episode
from agrisim.scene.camera import CameraModel
from agrisim.scene.transforms import look_at

#: the bench: a species a pot, two rows of three, 0.5 m apart
SPECIES = ["indian_cress", "hydrangea", "coltsfoot", "boston_fern", "chinese_evergreen", "amaryllis"]
#: one colour a plant of the masks (plant 0, none: white)
COLOURS = np.array(
    [[255, 255, 255], [230, 25, 75], [60, 180, 75], [255, 200, 25], [0, 130, 200], [245, 130, 48], [145, 30, 180]],
    np.uint8,
)
#: the outside view's size; each camera view keeps its camera's aspect at a third of its width
SIZE = (720, 400)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("docs/bench.png"))
    args = parser.parse_args()
    plants = [{"plant": name, "x": (k % 3 - 1) * 0.5, "y": (k // 3 - 0.5) * 0.5} for k, name in enumerate(SPECIES)]
    config = build_config(
        {
            "rig": {"backend": "gantry"},
            "bench": {"plants": plants},
            "routine": {"setpoints": "2x6"},
            "physics": {"backend": "kinematic"},
            "recon": {"backend": "none"},
            "renderer": {"raycast": {"shadow_samples": 16}},  # soft shadows without speckle
            "output": {"no_rrd": True},
        }
    )
    episode = Episode(config)
    spec = episode.registry.get("renderer", "raycast")
    options = backend_options(spec.options_model, config.renderer.options_for("raycast"), "raycast")
    renderer = episode.registry.build("renderer", spec, episode.scene, episode.cell, config.render, options)
    arm = episode.cell.arms[0]
    kin = episode.kinematics[arm.name]
    setpoints = episode.setpoints[arm.name]
    rng = np.random.default_rng(0)

    def posed(k: int) -> dict:
        found = kin.ik(setpoints[k].world_T_camera, np.array(arm.home), rng=rng)
        return {arm.name: kin.link_poses(found.q if found.ok else np.array(arm.home))}

    chosen = [len(setpoints) * i // 3 + 2 for i in range(3)]
    w, h = SIZE
    wide = CameraModel(w, h, 0.5 * w, 0.5 * w, (w - 1) / 2, (h - 1) / 2)
    centre = episode.cell.plant_center + np.array([0.0, 0.0, 0.2])
    outside = renderer.render(wide, look_at(centre + np.array([1.4, -2.6, 1.7]), centre), posed(chosen[0])).rgb
    c, third = episode.camera, w // 3
    k = third / c.width
    small = CameraModel(third, round(c.height * k), c.fx * k, c.fy * k, (c.cx + 0.5) * k - 0.5, (c.cy + 0.5) * k - 0.5)
    image = Image.new("RGB", (w, 28 + h + 2 * small.height), "white")
    image.paste(Image.fromarray(outside), (0, 28))
    for i, frame in enumerate(chosen):
        view = renderer.render(small, setpoints[frame].world_T_camera, posed(frame))
        assert view.plants is not None
        image.paste(Image.fromarray(view.rgb), (i * third, 28 + h))
        image.paste(Image.fromarray(COLOURS[view.plants]), (i * third, 28 + h + small.height))
    ImageDraw.Draw(image).text(
        (8, 8), "agrisim run --rig gantry --bench ... : six species, each plant's pixels known (plants/)", fill="black"
    )
    renderer.close()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    # 256 colours: a third of the size, the renders' look kept (docs' pictures travel with the repo)
    image.quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(args.out, optimize=True)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

"""Draw each built-in rig around its plant to ``docs/rigs.png`` (the Rigs guide's picture):
for each, the cell seen from outside with its arms at home (raycast, the arms drawn), and one
view of its own camera at a setpoint. Run: ``python bench/figure_rigs.py [--out PNG]``."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from agrisim.config import backend_options, build_config
from agrisim.episode import Episode
from agrisim.scene.camera import CameraModel
from agrisim.scene.transforms import look_at

#: (title, the run's settings): each rig as a user would start it
RIGS = [
    ("paper: two UR10s, the hemisphere", {}),
    ("single-arm --robot xarm7", {"rig": {"backend": "single-arm", "single-arm": {"robot": "xarm7"}}}),
    (
        "turntable, in the cabinet room (--rig turntable)",
        {"rig": {"backend": "turntable"}, "routine": {"setpoints": "3x8"}},
    ),
    ("gantry: an XYZ stage, a pan-tilt camera (--rig gantry)", {"rig": {"backend": "gantry"}}),
]
#: where the outside camera stands, relative to the plant, m: far enough for the paper's arms and
#: the gantry's portal, within the cabinet's backdrop (1.5 m) for the turntable
OUTSIDE = {
    "paper": np.array([1.7, -2.3, 1.3]),
    "single-arm": np.array([1.2, -1.6, 0.9]),
    "turntable": np.array([0.7, -1.0, 0.6]),
    "gantry": np.array([1.1, -1.9, 1.5]),
}
#: the outside view's size; the rig's own view keeps its camera's aspect at this width
SIZE = (480, 320)


def panel(settings: dict, title: str) -> Image.Image:
    """The rig from outside above, its camera's view below, the title on top."""
    base = {
        "plant": "hydrangea",
        "physics": {"backend": "kinematic"},
        "recon": {"backend": "none"},
        "renderer": {"raycast": {"shadow_samples": 16}},  # soft shadows without speckle
    }
    config = build_config({**base, **settings, "output": {"no_rrd": True}})
    episode = Episode(config)
    spec = episode.registry.get("renderer", "raycast")
    options = backend_options(spec.options_model, config.renderer.options_for("raycast"), "raycast")
    renderer = episode.registry.build("renderer", spec, episode.scene, episode.cell, config.render, options)
    # every arm at its setpoint a third of the way through its routine (as at one step of a run:
    # a turntable's cameras all at one stage angle)
    rng = np.random.default_rng(0)
    poses, views = {}, {}
    for arm in episode.cell.arms:
        kin, home = episode.kinematics[arm.name], np.array(arm.home)
        sps = episode.setpoints.get(arm.name, [])
        q = home
        if sps:
            views[arm.name] = sps[len(sps) // 3].world_T_camera
            found = kin.ik(views[arm.name], home, rng=rng)
            q = found.q if found.ok else home
        poses[arm.name] = kin.link_poses(q)
    w, h = SIZE
    wide = CameraModel(w, h, 0.55 * w, 0.55 * w, (w - 1) / 2, (h - 1) / 2)
    centre = episode.cell.plant_center + np.array([0.0, 0.0, 0.25])
    outside = renderer.render(wide, look_at(centre + OUTSIDE[config.rig.backend], centre), poses).rgb
    # the first arm's view there, through the run's camera scaled to the panel's width
    view = next(iter(views.values()))
    c = episode.camera
    k = w / c.width
    own_camera = CameraModel(w, round(c.height * k), c.fx * k, c.fy * k, (c.cx + 0.5) * k - 0.5, (c.cy + 0.5) * k - 0.5)
    own = renderer.render(own_camera, view, poses).rgb
    image = Image.new("RGB", (w, h + own_camera.height + 28), "white")
    image.paste(Image.fromarray(outside), (0, 28))
    image.paste(Image.fromarray(own), (0, 28 + h))
    ImageDraw.Draw(image).text((8, 8), title, fill="black")
    return image


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("docs/rigs.png"))
    args = parser.parse_args()
    panels = [panel(settings, title) for title, settings in RIGS]
    sheet = Image.new("RGB", (sum(p.width for p in panels) + 8 * (len(panels) - 1), panels[0].height), "white")
    x = 0
    for p in panels:
        sheet.paste(p, (x, 0))
        x += p.width + 8
    args.out.parent.mkdir(parents=True, exist_ok=True)
    # 256 colours: a third of the size, the renders' look kept (docs' pictures travel with the repo)
    sheet.quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(args.out, optimize=True)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

"""A run of the paper's rig in the ``cabinet`` room (``--set room.backend=cabinet``): the two UR10s
and their stands stand inside the default backdrop (1.5 m; the stands reach 1.22 m from the
axis), the saved scene is the cabinet's with the plant in its pot, and the images are exposed:
neither black nor blown out."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh
from PIL import Image

from agrisim.files import layout


def test_a_paper_run_takes_place_in_the_cabinet(tmp_path: Path, cli) -> None:  # noqa: ANN001
    out = tmp_path / "run"
    args = ["run", "--physics", "kinematic", "--setpoints", "1x3", "--resolution", "96x54", "--recon", "none"]
    code, _, err = cli([*args, "--no-rrd", "--set", "room.backend=cabinet", "--out", str(out)])
    assert code == 0, err
    names = set(trimesh.load(out / layout.SCENE_GLB, force="scene").geometry)
    assert {"floor", "backdrop", "ceiling", "lamp_panel", "stage", "table", "pot", "soil", "plant"} <= names, names
    assert not any(n.startswith(("cabinet_", "pallet_", "drum_", "walls")) for n in names), names  # no lab
    frames = sorted((out / "rgb").glob("*.png"))
    assert len(frames) == 6  # 2 arms x 3 setpoints
    for path in frames:
        rgb = np.asarray(Image.open(path))[..., :3].astype(float)
        labels = np.asarray(Image.open(out / "labels" / path.name))
        assert (labels > 0).sum() > 20, f"{path.name}: the plant is not in view"
        room = rgb[labels == 0]
        # the backdrop and floor lit by the one lamp: mid-tones, not the 0 of an unlit room or 255
        assert 40 < np.median(room) < 220 and (room >= 250).mean() < 0.05, f"{path.name}: {np.median(room)}"


def test_a_backdrop_through_the_stands_is_refused_before_anything_is_written(tmp_path: Path, cli) -> None:  # noqa: ANN001
    out = tmp_path / "never"
    args = ["run", "--physics", "kinematic", "--setpoints", "1x3", "--resolution", "96x54", "--recon", "none"]
    code, _, err = cli(
        [*args, "--no-rrd", "--set", "room.backend=cabinet", "--set", "room.cabinet.radius=1.1", "--out", str(out)]
    )
    assert code == 2 and "r1_stand reaches 1.22 m" in err and "room.cabinet.radius" in err, err
    assert not out.exists()

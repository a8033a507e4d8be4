"""The recording's default layout in Rerun's viewer (its blueprint): the 3D scene beside each
arm's camera images, depths and the camera error's time series."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import rerun.blueprint as rrb

from .entities import paths

if TYPE_CHECKING:
    from agrisim.robot.cell import Cell

#: where the 3D view's eye starts, from the plant (metres, world z up)
EYE_OFFSET = np.array([0.4, -2.2, 1.1])


def blueprint(cell: Cell) -> rrb.Blueprint:
    """The default layout: the cell in 3D; per arm, its camera's photograph (labels, leaf
    instances and a bench's plants as overlays, off) and, in a panel of its own, its depth; the reach errors.

    Everything else the recording holds stays in the views, hidden but one click (the eye in
    the blueprint panel) from showing: in 3D, each view's back-projected depth and cloud,
    which drawn at once bury the cell and the merged clouds, and the labels over the image
    planes.

    No timeline is named. Rerun's gRPC server, which ``agrisim view`` and ``--serve-web``
    serve through, replays blueprints ahead of all data, and a viewer told to show a
    timeline it holds no row on yet notices "Timeline sim_time not found". Unnamed, the
    viewer takes the timeline with the most rows; every temporal row carries both, and the
    tie goes to the later name, ``sim_time``.
    """
    arms = cell.arm_names
    hidden = rrb.EntityBehavior(visible=False)
    overlays = ("labels", "instances", *((paths.PLANTS,) if cell.bench else ()))
    cameras = [
        rrb.Spatial2DView(
            origin=paths.camera(a),
            name=f"{a} camera",
            # held but off: a click on their eye lays them over the photograph
            contents=[f"$origin/{kind}" for kind in ("rgb", *overlays)],
            overrides={paths.camera_image(a, kind): hidden for kind in overlays},
        )
        for a in arms
    ]
    depths = [rrb.Spatial2DView(origin=paths.camera(a), name=f"{a} depth", contents=["$origin/depth"]) for a in arms]
    # (Any: Rerun's override mapping is invariant in its key and value types)
    in_3d_hidden: dict[Any, Any] = {paths.VIEW_CLOUDS: hidden}
    for a in arms:
        in_3d_hidden |= {paths.camera_image(a, kind): hidden for kind in ("depth", paths.DEPTH_TRUTH, *overlays)}
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(
                origin=paths.WORLD,
                name="cell",
                overrides=in_3d_hidden,
                # the eye inside the room, above the table, the plant and both arms in view
                # (Rerun's default eye frames the whole room from outside its walls)
                eye_controls=rrb.EyeControls3D(
                    position=(cell.plant_center + EYE_OFFSET).tolist(),
                    look_target=cell.plant_center.tolist(),
                    eye_up=(0.0, 0.0, 1.0),
                ),
            ),
            rrb.Vertical(
                *cameras,
                rrb.Horizontal(*depths, name="depth (mm)"),
                rrb.TimeSeriesView(origin=paths.METRICS, name="camera error (mm)"),
                row_shares=[3] * len(cameras) + [2, 2],
            ),
            column_shares=[2, 1],
        ),
        collapse_panels=False,
    )

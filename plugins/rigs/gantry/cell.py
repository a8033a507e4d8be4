"""The gantry cell: the plant table and pot as the paper has them (``[cell]``), a portal of four
posts and two rails around them, and the robot ``g1``: the XYZ stage and its pan-tilt camera
(:mod:`.urdf`). The routine is the whole hemisphere around the plant for one camera: the grid's
levels are the polar angles of ``[routine] phi_deg``, its columns azimuths over a whole turn, in
snake order; each viewpoint's joints are solved in closed form and its pose is the robot's
forward kinematics there, so every setpoint is reachable by construction."""

from __future__ import annotations

import math

import numpy as np

from agrisim.config import CellConfig, RoutineConfig, parse_grid
from agrisim.errors import UserError
from agrisim.interfaces import Rig
from agrisim.plugins.rigs.gantry import GantryOptions
from agrisim.plugins.rigs.gantry.urdf import HEAD_TOP, JOINTS, gantry_urdf, portal, viewpoint_joints, z_max
from agrisim.plugins.rigs.paper.cell import plant_table
from agrisim.robot.cell import Arm, Cell, Cylinder
from agrisim.robot.kinematics import ArmKinematics
from agrisim.robot.setpoints import Setpoint
from agrisim.robot.urdf import CAMERA_FRAME
from agrisim.scene.transforms import look_at, translation

__all__ = ["ARM", "GantryRig", "hemisphere_views"]

#: the robot's name (frames g1_000, g1_001, ...)
ARM = "g1"
#: a viewpoint this close beyond a joint limit is within it, m or rad (the rounding of the
#: hemisphere's trigonometry)
LIMIT_SLACK = 1e-9
#: the stage's travel in x and y over one plant, m (a bench's adds twice its farthest plant's offset)
TRAVEL = 1.2
#: a bench's viewpoint closer than this to a neighbour's keep-out is left out, m (the head's size)
NEIGHBOUR_CLEARANCE = 0.08


def hemisphere_views(centre: np.ndarray, routine: RoutineConfig) -> list[tuple[float, float, np.ndarray]]:
    """The routine's viewpoints around ``centre`` in shooting order: (polar angle, azimuth, world_T_camera).

    ``L x C``: L polar angles from the zenith over ``phi_deg`` (top level first), C azimuths a
    whole turn apart by 360/C degrees, the first half a step from +x (so that a level's camera
    pans within -180..180 degrees without crossing the back of its range); levels alternate
    direction (snake order), so consecutive viewpoints are neighbours. Cameras sit ``radius``
    from ``centre`` and look at the point ``aim_height`` above it (:func:`look_at`).
    ``theta_deg`` (a paper arm's half) does not apply: one camera goes all the way round.
    """
    levels, columns = parse_grid(routine.setpoints)
    phis = np.radians(np.linspace(*routine.phi_deg, levels))
    azimuths = (np.arange(columns) + 0.5) * (2.0 * math.pi / columns)
    aim = centre + np.array([0.0, 0.0, routine.aim_height])
    out = []
    for i, phi in enumerate(phis):
        for azimuth in azimuths if i % 2 == 0 else azimuths[::-1]:
            direction = np.array([math.sin(phi) * math.cos(azimuth), math.sin(phi) * math.sin(azimuth), math.cos(phi)])
            out.append((float(phi), float(azimuth), look_at(centre + routine.radius * direction, aim)))
    return out


class GantryRig(Rig):
    """A Cartesian gantry over the plant (``[rig.gantry]``); ``[cell]`` sizes the table, the pot
    and the keep-out; ``[cell] arms`` and the stands do not apply.

    ``notes`` holds the lines ``agrisim run`` prints about the gantry and its routine."""

    options: GantryOptions

    def __init__(self, settings: CellConfig, options: GantryOptions | None = None) -> None:
        super().__init__(settings, options if options is not None else GantryOptions())
        self.notes: list[str] = []

    @property
    def travel(self) -> tuple[float, float]:
        """The stage's travel in x and y, m: the options', else :data:`TRAVEL` plus twice the
        bench's farthest plant's offset along the axis."""
        far = np.abs([p.xy for p in self.bench]).max(axis=0) if self.bench else np.zeros(2)
        given = (self.options.travel_x, self.options.travel_y)
        return tuple(float(t) if t is not None else round(TRAVEL + 2 * f, 6) for t, f in zip(given, far, strict=True))  # type: ignore[return-value]

    def cell(self) -> Cell:
        cfg, o = self.settings, self.options
        centre = np.array([0.0, 0.0, cfg.table_height])
        obstacles = plant_table(cfg)
        travel = self.travel
        obstacles += portal(travel, o.beam_height, centre)
        urdf = gantry_urdf(
            ARM,
            travel=travel,
            beam_height=o.beam_height,
            z_min=o.z_min,
            speeds=(o.speed_x, o.speed_y, o.speed_z),
            head_speed=math.radians(o.pan_tilt_speed_deg_s),
        )
        # home: the camera as high as it goes straight above the plant, looking down on it
        home = (0.0, 0.0, z_max(o.beam_height), 0.0, math.pi / 2)
        arm = Arm(
            name=ARM,
            urdf=urdf,
            world_T_base=translation(centre[0], centre[1], 0.0),
            stand="portal_post_1",
            joints=JOINTS,
            camera_frame=CAMERA_FRAME,
            home=home,
            accelerations=(o.acceleration,) * 3 + (math.radians(o.pan_tilt_acceleration_deg_s2),) * 2,
        )
        if not self.notes:
            self.notes.append(
                f"gantry {ARM}: travel {travel[0]:g} x {travel[1]:g} m, the camera from {o.z_min:.2f} to "
                f"{z_max(o.beam_height):.2f} m above the floor under rails at {o.beam_height:g} m; x and y at "
                f"{o.speed_x:g} and {o.speed_y:g} m/s, z at {o.speed_z:g} m/s, the head at {o.pan_tilt_speed_deg_s:g} deg/s"
            )
        return Cell(arms=(arm,), obstacles=tuple(obstacles), plant_center=centre)

    def setpoints(self, cell: Cell, routine: RoutineConfig) -> dict[str, list[Setpoint]]:
        """The whole hemisphere (:func:`hemisphere_views`) for the camera: each viewpoint's
        joints in closed form (:func:`.urdf.viewpoint_joints`), its pose the gantry's forward
        kinematics there. A viewpoint beyond the gantry's travel is refused (:class:`UserError`)."""
        arm = cell.arm(ARM)
        kin = ArmKinematics(arm)
        if cell.bench:
            views, note = self._bench_views(cell, routine)
        else:
            views = hemisphere_views(cell.plant_center, routine)
            levels, columns = parse_grid(routine.setpoints)
            note = (
                f"the whole hemisphere for one camera: {levels} level(s) x {columns} azimuths over a turn, "
                f"radius {routine.radius:g} m"
            )
        joints = [viewpoint_joints(T, arm.world_T_base) for _, _, T in views]
        self._check_travel(kin, views, joints)
        if note not in self.notes:  # a tool may ask the same rig for its routine more than once
            self.notes.append(note)
        return {arm.name: [Setpoint(arm.name, k, kin.fk(q)) for k, q in enumerate(joints)]}

    def _bench_views(self, cell: Cell, routine: RoutineConfig) -> tuple[list[tuple[float, float, np.ndarray]], str]:
        """A bench's viewpoints: the hemisphere around each plant, the plants in the order of a
        short tour (each next the nearest not yet visited, from ``plant_01``), without the
        viewpoints that come within :data:`NEIGHBOUR_CLEARANCE` of another plant's keep-out."""
        keepouts = {
            ob.name.removeprefix("plant_keepout"): ob
            for ob in cell.obstacles
            if ob.name.startswith("plant_keepout_") and isinstance(ob, Cylinder)
        }
        todo, tour = list(cell.bench[1:]), [cell.bench[0]]
        while todo:
            here = np.array(tour[-1].xy)
            tour.append(todo.pop(int(np.argmin([np.hypot(*(np.array(p.xy) - here)) for p in todo]))))
        views, dropped = [], 0
        for plant in tour:
            centre = cell.plant_center + np.array([*plant.xy, 0.0])
            others = [ob for key, ob in keepouts.items() if key != plant.name.removeprefix("plant")]
            for view in hemisphere_views(centre, routine):
                if any(_near(view[2][:3, 3], ob) for ob in others):
                    dropped += 1
                else:
                    views.append(view)
        levels, columns = parse_grid(routine.setpoints)
        note = (
            f"a bench of {len(tour)}: the hemisphere around each plant ({levels} level(s) x {columns} azimuths, "
            f"radius {routine.radius:g} m), in the order {', '.join(p.name for p in tour)}"
            + (
                f"; {dropped} viewpoints left out, within {NEIGHBOUR_CLEARANCE:g} m of a neighbour's keep-out "
                "(a larger --spacing or a smaller routine.radius keeps them)"
                if dropped
                else ""
            )
        )
        return views, note

    def _check_travel(
        self, kin: ArmKinematics, views: list[tuple[float, float, np.ndarray]], joints: list[np.ndarray]
    ) -> None:
        """Refuse the routine in one line when a viewpoint lies beyond a joint's range: the first
        such viewpoint, what it needs and what the gantry allows, and the settings that would
        reach every viewpoint."""
        o = self.options
        lower, upper = kin.lower - LIMIT_SLACK, kin.upper + LIMIT_SLACK
        outside = [k for k, q in enumerate(joints) if np.any((q < lower) | (q > upper))]
        if not outside:
            return
        k = outside[0]
        q, (phi, azimuth, _) = joints[k], views[k]
        where = (
            f"rig gantry: {len(outside)} of {len(joints)} viewpoints are beyond the gantry's travel; "
            f"{ARM}_{k:03d} (polar {math.degrees(phi):.0f}, azimuth {math.degrees(azimuth):.0f} degrees) needs "
        )
        if not lower[0] <= q[0] <= upper[0] or not lower[1] <= q[1] <= upper[1]:
            i = 0 if not lower[0] <= q[0] <= upper[0] else 1
            span = self.travel[i]
            what = f"{'xy'[i]} = {q[i]:+.3f} m from the plant's axis, beyond +-{span / 2:.3f} m (rig.gantry.travel_{'xy'[i]} = {span:g})"
        elif not lower[2] <= q[2] <= upper[2]:
            what = f"the camera {q[2]:.3f} m above the floor, " + (
                f"below the ram's lowest (rig.gantry.z_min = {o.z_min:g})"
                if q[2] < lower[2]
                else f"above the ram's highest ({kin.upper[2]:.3f} m under rails at rig.gantry.beam_height = {o.beam_height:g})"
            )
        else:  # look_at never rolls the image nor tilts past straight down: a viewpoint of another routine
            what = (
                f"the head at pan {math.degrees(q[3]):.1f}, tilt {math.degrees(q[4]):.1f} degrees, beyond its range "
                f"(pan +-{math.degrees(kin.upper[3]):g}, tilt +-{math.degrees(kin.upper[4]):g})"
            )
            raise UserError(where + what)
        # what would reach them all: each setting rounded outwards to the centimetre
        Q = np.array(joints)
        needs, instead = [], []
        for i, axis in enumerate("xy"):
            if (np.abs(Q[:, i]) > upper[i]).any():
                needs.append(f"rig.gantry.travel_{axis} >= {math.ceil(200 * np.abs(Q[:, i]).max()) / 100:.2f}")
                instead.append("a smaller routine.radius")
        if (Q[:, 2] < lower[2]).any():
            needs.append(f"rig.gantry.z_min <= {math.floor(100 * Q[:, 2].min()) / 100:.2f}")
            instead.append("a smaller largest routine.phi_deg")
        if (Q[:, 2] > upper[2]).any():
            needs.append(f"rig.gantry.beam_height >= {math.ceil(100 * (Q[:, 2].max() + HEAD_TOP)) / 100:.2f}")
            instead.append("a smaller routine.radius")
        raise UserError(
            f"{where}{what}; to reach every viewpoint set {' and '.join(needs)}, or choose "
            + " and ".join(dict.fromkeys(instead))
        )


def _near(p: np.ndarray, keepout: Cylinder) -> bool:
    """Is ``p`` within :data:`NEIGHBOUR_CLEARANCE` of the cylinder ``keepout``?"""
    c = keepout.world_T[:3, 3]
    return bool(
        np.hypot(p[0] - c[0], p[1] - c[1]) < keepout.radius + NEIGHBOUR_CLEARANCE
        and abs(p[2] - c[2]) < keepout.height / 2 + NEIGHBOUR_CLEARANCE
    )

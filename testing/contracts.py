"""The contract every backend of a kind must keep, as checks a test suite can run.

agrisim's own suite runs them over every registered backend (``tests/contracts``); a plugin
author runs them on their backend the same way::

    from agrisim.registry import Registry, make_plugin_manager
    from agrisim.testing.contracts import check

    def test_my_renderer_keeps_the_contract():
        check("renderer", "mine", Registry(make_plugin_manager()))

Each check builds the backend through the registry (so its factory's result is type-checked),
drives it on a small situation whose right answer is known from geometry, and raises
``AssertionError`` saying what broke. They run on a CPU in seconds.
"""

from __future__ import annotations

import json
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from agrisim.config import ImagerConfig, RenderConfig, RoutineConfig, RunConfig
from agrisim.errors import UserError
from agrisim.interfaces import ALL, Exposure, Frame, JointTrajectory, PlanningFailed, View, view_key
from agrisim.kinds import KINDS, BackendSpec
from agrisim.registry import Registry
from agrisim.robot.cell import Cell
from agrisim.robot.segments import path_is_valid
from agrisim.scene.camera import CameraModel, from_fov
from agrisim.scene.model import PLANT_FIT_HEIGHT, PLANT_FIT_RADIUS, Label, LabelTable, Plant
from agrisim.scene.transforms import look_at
from agrisim.validation import open_rig

__all__ = [
    "check",
    "check_exporter",
    "check_format",
    "check_imager",
    "check_physics",
    "check_planner",
    "check_plant",
    "check_poses",
    "check_reconstructor",
    "check_renderer",
    "check_rig",
    "check_room",
    "check_sensor",
]


def check(kind: str, name: str, registry: Registry, options: Any = None) -> None:
    """Run the contract of ``kind`` on the backend ``name`` (with its default options unless
    ``options`` is given)."""
    if kind not in CHECKS:
        raise ValueError(f"no contract for kind {kind!r}; kinds with one: {', '.join(CHECKS)}")
    spec = registry.get(kind, name)
    CHECKS[kind](registry, spec, spec.options_model() if options is None else options)


def _cell(registry: Registry) -> Cell:
    """The cell of the default rig (the paper's), the situation most contracts are checked in."""
    return open_rig(RunConfig(), registry)[1]


# ------------------------------------------------------------------------------- physics


def check_physics(registry: Registry, spec: BackendSpec, options: Any) -> None:
    """A short joint move of one arm in free air: the backend reports where the arms start,
    executes the trajectory in simulated time, reaches the goal it was sent to, and leaves the
    other arm where it was."""
    cell = _cell(registry)
    physics = registry.build("physics", spec, cell, options)
    try:
        homes = {arm.name: np.array(arm.home, float) for arm in cell.arms}
        for name, home in homes.items():
            assert np.allclose(physics.joint_positions(name), home, atol=1e-6), f"{name} does not start at home"
        home = homes["r1"]
        goal = home + np.array([0.3, -0.15, 0.1, 0.2, 0.0, 0.3])
        assert not physics.in_collision("r1", home) and not physics.in_collision("r1", goal)
        t = np.linspace(0.0, 1.0, 241)
        s = 3 * t**2 - 2 * t**3  # rest to rest
        plan = JointTrajectory(t, home + np.outer(s, goal - home))
        t0 = physics.sim_time
        out = physics.execute({"r1": plan}, lambda robot, q: float(np.max(np.abs(q - goal))) < 1e-3, timeout=5.0)
        ex = out["r1"]
        assert ex.settled, f"r1 did not settle within 1e-3 rad of the goal (reached {physics.joint_positions('r1')})"
        assert np.max(np.abs(physics.joint_positions("r1") - goal)) < 1e-3
        assert physics.sim_time >= t0 + plan.duration - 1e-9, "less simulated time passed than the plan lasts"
        times = ex.executed.t
        assert len(times) > 1 and np.all(np.diff(times) > 0), "executed times must increase"
        assert np.max(np.abs(ex.executed.q[0] - home)) < 0.05 and np.max(np.abs(ex.executed.q[-1] - goal)) < 1e-3
        assert ex.contacts == [], f"contacts in free air: {ex.contacts}"
        for name, home_other in homes.items():
            if name != "r1":
                assert np.allclose(physics.joint_positions(name), home_other, atol=1e-3), f"{name} moved"
    finally:
        physics.close()


# ------------------------------------------------------------------------------- planners


def _wall(q: np.ndarray) -> bool:
    """Joint space with a slab across joint 0, open only where joint 1 is above 1.5 rad."""
    return not (abs(q[0]) < 0.3 and q[1] < 1.5)


def check_planner(registry: Registry, spec: BackendSpec, options: Any) -> None:
    """A free problem gets a path; a problem with a wall in the way gets a path that keeps
    clear of it at the stated resolution, or :class:`PlanningFailed`; never a path that is not
    valid, nor one that does not join start and goal."""
    planner = registry.build("planner", spec, options)
    lower, upper = np.full(6, -np.pi), np.full(6, np.pi)
    resolution = 0.02
    free = planner.plan(np.zeros(6), np.full(6, 0.5), lambda q: True, lower, upper, 0, resolution)
    _assert_joins(free, np.zeros(6), np.full(6, 0.5))
    start, goal = np.array([-2.0, 0, 0, 0, 0, 0]), np.array([2.0, 0, 0, 0, 0, 0])
    try:
        path = planner.plan(start, goal, _wall, lower, upper, 0, resolution)
    except PlanningFailed:
        return
    _assert_joins(path, start, goal)
    assert path_is_valid(np.asarray(path), _wall, resolution), "the path crosses the wall at the stated resolution"


def _assert_joins(path: np.ndarray, start: np.ndarray, goal: np.ndarray) -> None:
    path = np.asarray(path, float)
    assert path.ndim == 2 and path.shape[1] == len(start) and len(path) >= 2, f"path of shape {path.shape}"
    assert np.allclose(path[0], start) and np.allclose(path[-1], goal), "the path must run from start to goal"


# ------------------------------------------------------------------------------- renderers


def _plant_scene(registry: Registry, cell: Cell, labels: str) -> tuple[Any, Plant]:
    """The lab with the hydrangea (four organs, leaf instances), both through the registry as a
    run builds them (the plant kept on disk where ``AGRISIM_PLANT_CACHE`` says: every renderer
    and sensor check draws the same plant)."""
    from agrisim.scene.plant_cache import grown

    spec = registry.get("plant", "hydrangea")
    options = spec.options_model()
    plant = grown("hydrangea", options, 0, registry.build("plant", spec, options).build)
    lab = registry.get("room", "lab")
    room = registry.build("room", lab, cell, lab.options_model())
    return room.scene(plant, seed=42, labels=labels), plant


def check_renderer(registry: Registry, spec: BackendSpec, options: Any) -> None:
    """Draws what the interface promises, where the geometry says it is.

    * Looking straight down 1 m above bare floor (arms hidden): depth is the planar 1 m
      everywhere, every pixel is background.
    * Looking down at the plant: plant pixels exist, carry ids of the plant's label table, and
      back-project into the plant's bounding box; declared capabilities hold (organ labels
      give more than one organ; leaf instances are uint16 and lie exactly on the leaf pixels).
    """
    caps = spec.capabilities
    cell = _cell(registry)
    mode = "texture" if "texture" in caps.seg_modes else sorted(caps.seg_modes)[0]
    labels = "organs" if caps.organ_labels else "plant"
    scene, plant = _plant_scene(registry, cell, labels)
    # seg_modes are plain strings (a plugin may declare any): the model validates the one taken
    settings = RenderConfig.model_validate({"seg_mode": mode, "labels": labels, "hide_robots": True})
    renderer = registry.build("renderer", spec, scene, cell, settings, options)
    camera = from_fov(60.0, 160, 120)
    poses: dict[str, dict[str, np.ndarray]] = {}
    try:
        floor = renderer.render(camera, look_at(np.array([0.0, 1.2, 1.0]), np.array([0.0, 1.2, 0.0])), poses)
        _assert_frame(floor, camera)
        assert not floor.labels.any(), "bare floor labelled as plant"
        assert np.allclose(floor.depth, 1.0, atol=0.01), (
            f"floor depth {floor.depth.min():.4f}..{floor.depth.max():.4f}, not 1 m"
        )

        top = cell.plant_center + np.array([0.0, 0.0, 1.0])
        world_T_camera = look_at(top, cell.plant_center)
        frame = renderer.render(camera, world_T_camera, poses)
        _assert_frame(frame, camera)
        plant_px = frame.labels > 0
        assert plant_px.sum() > 100, "the plant below the camera is (almost) not drawn"
        ids = set(np.unique(frame.labels[plant_px]).tolist())
        assert ids <= {lab.id for lab in scene.labels.labels if lab.id}, f"label ids {ids} not in the table"
        if caps.organ_labels:
            assert len(ids) > 1, "declares organ labels, drew one label"
        points = _backproject(frame.depth, plant_px, camera, world_T_camera)
        placed = scene.mesh(scene.plant).vertices  # the plant where the scene put it, world frame
        lo, hi = placed.min(axis=0) - 0.01, placed.max(axis=0) + 0.01
        inside = np.all((points >= lo) & (points <= hi), axis=1).mean()
        assert inside > 0.99, f"only {inside:.1%} of plant pixels back-project into the plant's bounds"
        if caps.leaf_instances:
            assert frame.instances is not None and frame.instances.dtype == np.uint16
            leaf = scene.labels.by_name("leaf").id
            assert np.array_equal(frame.instances > 0, frame.labels == leaf), "instances off the leaf pixels"
    finally:
        renderer.close()


def check_sensor(registry: Registry, spec: BackendSpec, options: Any) -> None:
    """Measures depth where the geometry says it is.

    * Its geometry is None (it measures on the colour camera's own pixels) or an imager and a
      rigid pose beside the camera (a rotation, within 20 cm).
    * Looking straight down at the plant from a height above its top inside the sensor's
      declared range (1 m where the range holds it; arms hidden, the raycast renderer's frame
      given): it returns None (the exact depth is its measurement) or H x W float32 planar
      depth, 0 where it measures nothing. It measures at least a fifth of the pixels; where the
      exact depth is known, its median relative error is under 2% (the D4xx datasheet's
      absolute accuracy) and 60% of its pixels lie within 5% (edges may fly or fatten).
    """
    cell = _cell(registry)
    scene, _ = _plant_scene(registry, cell, "plant")
    settings = RenderConfig.model_validate({"hide_robots": True})
    drawer = registry.get("renderer", "raycast")
    renderer = registry.build("renderer", drawer, scene, cell, settings, drawer.options_model(shadow_samples=0))
    sensor = registry.build("sensor", spec, scene, cell, settings, options)
    camera = from_fov(60.0, 160, 120)
    try:
        geometry = sensor.geometry(camera)
        if geometry is not None:
            T = np.asarray(geometry.camera_T_sensor, np.float64)
            _assert_rigid(T, "camera_T_sensor")
            assert np.linalg.norm(T[:3, 3]) < 0.2, "the sensor sits more than 20 cm from the camera"
            assert geometry.camera.width > 0 and geometry.camera.fx > 0, "the sensor's imager is no pinhole"
        lo, hi = spec.capabilities.range_m
        height = 1.0 if lo <= 1.0 <= hi else float(np.sqrt(lo * hi))
        top = scene.mesh(scene.plant).vertices.max(axis=0)
        eye = np.array([cell.plant_center[0], cell.plant_center[1], top[2] + height])
        world_T_camera = look_at(eye, np.array([cell.plant_center[0], cell.plant_center[1], 0.0]))
        frame = renderer.render(camera, world_T_camera, {})
        depth = sensor.measure(camera, world_T_camera, {}, frame)
        if depth is None:
            return
        assert depth.shape == (camera.height, camera.width) and depth.dtype == np.float32, (
            f"sensor depth must be H x W float32, got {depth.shape} {depth.dtype}"
        )
        assert np.all(np.isfinite(depth)) and np.all(depth >= 0), "sensor depth must be finite, 0 for none"
        both = (depth > 0) & (frame.depth > 0)
        assert both.sum() > depth.size / 5, f"the sensor measured only {both.sum()} of {depth.size} pixels"
        relative = depth[both] / frame.depth[both] - 1.0
        assert abs(float(np.median(relative))) < 0.02, (
            f"the plant {height:g} m below measured {np.median(relative):+.1%} off its exact depth"
        )
        # (stereo fattens the foreground at a plant's many edges: the D405 keeps 71% within 5%)
        assert np.mean(np.abs(relative) < 0.05) > 0.6, (
            f"the depth of the plant {height:g} m below strays: {np.mean(np.abs(relative) < 0.05):.0%} within 5%"
        )
    finally:
        sensor.close()
        renderer.close()


def check_room(registry: Registry, spec: BackendSpec, options: Any) -> None:
    """Places the plant where the cell says, and draws nothing else with a label.

    With the hydrangea (four organs) in the paper's cell, for each labels mode:

    * one mesh is the plant: named as the scene says, exactly where and as
      :func:`agrisim.robot.cell.place_plant` puts it (its vertices, its label table);
    * every other mesh is background: label 0, no label texture other than zeros;
    * there is a light; the same seed gives the same scene.
    """
    from agrisim.robot.cell import place_plant
    from agrisim.scene.model import Scene

    cell = _cell(registry)
    room = registry.build("room", spec, cell, options)
    _, plant = _plant_scene(registry, cell, "plant")
    for labels in ("plant", "organs"):
        scene = room.scene(plant, seed=3, labels=labels)
        assert isinstance(scene, Scene), f"scene() must return an agrisim.scene.model.Scene, got {type(scene).__name__}"
        placed = place_plant(plant, cell, labels)
        drawn = scene.mesh(scene.plant)
        assert np.array_equal(drawn.vertices, placed.mesh.vertices), f"labels={labels}: the plant is not on the soil"
        assert scene.labels.to_json() == placed.labels.to_json(), f"labels={labels}: the label table is not the plant's"
        for mesh in scene.meshes:
            if mesh.name == scene.plant:
                continue
            for m in mesh.materials:
                assert m.label == 0 and (m.labels is None or not np.any(m.labels)), (
                    f"mesh {mesh.name!r} is labelled: everything but the plant is background"
                )
        assert scene.lights, "the room lights nothing"
        again = room.scene(plant, seed=3, labels=labels)
        assert [m.name for m in again.meshes] == [m.name for m in scene.meshes] and all(
            np.array_equal(a.vertices, b.vertices) for a, b in zip(again.meshes, scene.meshes, strict=True)
        ), "the same seed gave another scene"


def check_rig(registry: Registry, spec: BackendSpec, options: Any) -> None:
    """Builds arms that exist and viewpoints they reach, looking at the plant.

    With the default ``[cell]`` settings and a 2 x 3 routine:

    * the cell has arms, named once each; each one's URDF loads in Pinocchio with its joints and
      camera frame, its home lies within its joint limits, its base pose is rigid and it stands
      on one of the cell's obstacles; the same settings give the same cell;
    * the setpoints are the cell's arms' (numbered 0, 1, ... in order), rigid poses, each with
      the plant centre in front of the camera within 45 degrees of its axis;
    * IK (collisions aside) brings each arm's camera to at least half its setpoints.
    """
    from agrisim.robot.kinematics import ArmKinematics
    from agrisim.robot.setpoints import Setpoint

    rig = registry.build("rig", spec, RunConfig().cell, options)
    cell = rig.cell()
    assert isinstance(cell, Cell), f"cell() must return an agrisim.robot.cell.Cell, got {type(cell).__name__}"
    names = [arm.name for arm in cell.arms]
    assert names and len(set(names)) == len(names), f"the cell's arms must be named once each: {names}"
    obstacles = {ob.name for ob in cell.obstacles}
    again = rig.cell()
    routine = RoutineConfig(setpoints="2x3")
    setpoints = rig.setpoints(cell, routine)
    assert set(setpoints) <= set(names) and setpoints, f"setpoints for arms {sorted(setpoints)}, arms are {names}"
    rng = np.random.default_rng(0)
    for arm, twin in zip(cell.arms, again.arms, strict=True):
        _assert_rigid(arm.world_T_base, f"{arm.name}'s base")
        assert arm.stand in obstacles, f"{arm.name} stands on {arm.stand!r}, not one of the cell's obstacles"
        assert np.array_equal(arm.world_T_base, twin.world_T_base), f"the same settings moved {arm.name}"
        kin = ArmKinematics(arm)
        home = np.asarray(arm.home, float)
        assert home.shape == (kin.dof,) and np.all((home >= kin.lower) & (home <= kin.upper)), (
            f"{arm.name}'s home {arm.home} is not within its joint limits"
        )
        reached = 0
        for k, sp in enumerate(setpoints.get(arm.name, [])):
            assert isinstance(sp, Setpoint) and (sp.robot, sp.index) == (arm.name, k), f"setpoint {sp} out of order"
            T = np.asarray(sp.world_T_camera, np.float64)
            _assert_rigid(T, f"setpoint {sp.frame}")
            ray = cell.plant_center - T[:3, 3]
            cos = float(T[:3, 2] @ ray) / max(float(np.linalg.norm(ray)), 1e-9)
            assert cos > np.cos(np.radians(45)), f"the camera at {sp.frame} does not look at the plant"
            reached += kin.ik(T, home, rng=rng, restarts=4, max_restarts=16).q is not None
        count = len(setpoints.get(arm.name, []))
        assert reached * 2 >= count, f"{arm.name} reaches {reached} of its {count} setpoints"


def _assert_rigid(T: np.ndarray, what: str) -> None:
    R = T[:3, :3]
    assert T.shape == (4, 4) and np.allclose(R @ R.T, np.eye(3), atol=1e-9) and np.linalg.det(R) > 0, (
        f"{what} is not a rigid pose"
    )


def check_format(registry: Registry, spec: BackendSpec, options: Any) -> None:
    """Claims files by their path alone, and refuses a file it claims but cannot read.

    * its suffixes are lower case with their dot, and it holds a ``mesh`` or a ``point cloud``;
    * it claims a path with each of its suffixes (in any case) that does not exist yet, and no
      path without a suffix;
    * asked to read a claimed path that does not exist, or that holds garbage, it raises a
      :class:`agrisim.errors.UserError` naming the file, in one line.
    """
    from agrisim.config import PlantFileConfig

    reader = registry.build("format", spec, options)
    assert reader.suffixes and all(x.startswith(".") and x == x.lower() for x in reader.suffixes), (
        f"suffixes must be lower case with their dot, got {reader.suffixes!r}"
    )
    assert reader.holds in ("mesh", "point cloud"), f"holds must be 'mesh' or 'point cloud', got {reader.holds!r}"
    with tempfile.TemporaryDirectory() as tmp:
        for suffix in reader.suffixes:
            for name in (f"plant{suffix}", f"PLANT{suffix.upper()}"):
                assert reader.claims(Path(tmp) / name), f"it does not claim {name}"
        assert not reader.claims(Path(tmp) / "plant"), "it claims a path without a suffix"
        missing, garbage = Path(tmp) / f"missing{reader.suffixes[0]}", Path(tmp) / f"garbage{reader.suffixes[0]}"
        garbage.write_bytes(bytes(range(256)) * 4)
        for path in (missing, garbage):
            try:
                reader.read(path, PlantFileConfig())
            except UserError as exc:
                assert path.name in str(exc) and "\n" not in str(exc).strip(), f"its refusal of {path.name}: {exc!r}"
            else:
                raise AssertionError(f"it read {path.name}, which holds no plant")


def check_poses(registry: Registry, spec: BackendSpec, options: Any) -> None:
    """Asked for the poses of a run it has estimated none for (a run directory of a run that
    saved no view), it refuses with a :class:`agrisim.errors.UserError` of one line and writes
    nothing there."""
    source = registry.build("poses", spec, options)
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp) / "run"
        run_dir.mkdir()
        run = {"status": "complete", "frames_complete": [], "labels": [], "config": {}, "results": []}
        (run_dir / "run.json").write_text(json.dumps(run))
        before = _tree(run_dir)
        try:
            source.poses(run_dir)
        except UserError as exc:
            assert str(exc) and "\n" not in str(exc).strip(), f"its refusal is not one line: {exc!r}"
        else:
            raise AssertionError("it gave poses for a run with no views")
        assert _tree(run_dir) == before, "asked for poses, it wrote into the run directory"


def check_imager(registry: Registry, spec: BackendSpec, options: Any) -> None:
    """Turns light into an image, the same for the same seed and view, brighter for more light.

    On a 48 x 64 radiance (a grey ramp, 0.05 to 0.6 of a white surface under irradiance 1):

    * a shot is H x W x 3 uint8 RGB, a raw frame and an exposure of positive time and gain;
    * a second imager of the same settings and seed gives the same bytes for the same view;
    * at the first shot's exposure (``at_exposure``), the shot records that exposure, and twice
      the light gives a brighter mean image (unless it was already white);
    * ``describe()`` is a JSON object naming the imager.
    """
    settings = ImagerConfig.model_validate({"model": spec.name})
    ramp = np.linspace(0.05, 0.6, 64, dtype=np.float32)
    radiance = np.repeat(np.broadcast_to(ramp, (48, 64))[..., None], 3, axis=2).copy()
    view = view_key("r1_000")
    first = registry.build("imager", spec, settings, 7, options).shoot(radiance, view)
    rgb = np.asarray(first.rgb)
    assert rgb.shape == (48, 64, 3) and rgb.dtype == np.uint8, (
        f"a shot's RGB must be H x W x 3 uint8, got {rgb.shape} {rgb.dtype}"
    )
    assert isinstance(first.exposure, Exposure) and first.exposure.time_s > 0 and first.exposure.gain > 0, (
        f"a shot's exposure must have a positive time and gain, got {first.exposure!r}"
    )
    assert np.asarray(first.raw).ndim in (2, 3), "a shot's raw frame must be an image"
    again = registry.build("imager", spec, settings, 7, options).shoot(radiance, view)
    assert np.array_equal(np.asarray(again.rgb), rgb), "the same settings, seed and view gave other bytes"
    fixed = registry.build("imager", spec, settings, 7, options).at_exposure(first.exposure)
    shot = fixed.shoot(radiance, view)
    assert (shot.exposure.time_s, shot.exposure.gain) == (first.exposure.time_s, first.exposure.gain), (
        f"at_exposure({first.exposure}) shot at {shot.exposure}"
    )
    dim, bright = float(np.asarray(shot.rgb).mean()), float(np.asarray(fixed.shoot(2 * radiance, view).rgb).mean())
    assert bright > dim or dim >= 254.0, (
        f"twice the light at one exposure gave a mean of {bright:.1f}, not above {dim:.1f}"
    )
    about = registry.build("imager", spec, settings, 7, options).describe()
    assert isinstance(about, dict) and about.get("name"), "describe() must be a dict with the imager's name"
    json.dumps(about)


def _assert_frame(frame: Any, camera: CameraModel) -> None:
    h, w = camera.height, camera.width
    assert frame.rgb.shape == (h, w, 3) and frame.rgb.dtype == np.uint8, f"rgb {frame.rgb.shape} {frame.rgb.dtype}"
    assert frame.labels.shape == (h, w) and frame.labels.dtype == np.uint8, "labels must be H x W uint8"
    assert frame.depth.shape == (h, w) and frame.depth.dtype == np.float32, "depth must be H x W float32"
    assert np.all(np.isfinite(frame.depth)) and np.all(frame.depth >= 0), "depth must be finite, 0 for no hit"


def _backproject(depth: np.ndarray, mask: np.ndarray, camera: CameraModel, world_T_camera: np.ndarray) -> np.ndarray:
    v, u = np.nonzero(mask)
    z = depth[v, u].astype(np.float64)
    xyz = np.column_stack([(u - camera.cx) / camera.fx * z, (v - camera.cy) / camera.fy * z, z])
    return xyz @ world_T_camera[:3, :3].T + world_T_camera[:3, 3]


# --------------------------------------------------------------------------- reconstructors


def check_reconstructor(registry: Registry, spec: BackendSpec, options: Any) -> None:
    """Twelve views, 1 cm apart, of the plane z = 1 m from 0.5 m above, its half x < 0
    labelled leaf and x > 0 stem: the result's merged clouds (per label and ``"all"``) lie on
    the plane in world coordinates, each label on its own half; declared result clouds and
    meshes too. (Twelve: a reconstructor that holds views out for testing has some.)"""
    table = LabelTable(
        [Label(0, "background", (0, 0, 0)), Label(1, "leaf", (0, 255, 0)), Label(2, "stem", (96, 0, 128))]
    )
    recon = registry.build("reconstructor", spec, table, options)
    camera = from_fov(60.0, 120, 90)
    plane_z = 1.0  # the plane z = 1 m, seen from 0.5 m above
    for k, x in enumerate(np.arange(12) * 0.01):
        # Image right is world +x; the plane's half x < 0 is leaf, x > 0 stem, in every view.
        world_T_camera = look_at(
            np.array([x, 0.0, plane_z + 0.5]), np.array([x, 0.0, plane_z]), up=np.array([0.0, 1.0, 0.0])
        )
        world_x = x + (np.arange(camera.width) - camera.cx) / camera.fx * 0.5
        labels = np.where(world_x < 0.0, 1, 2).astype(np.uint8)[None, :].repeat(camera.height, 0)
        images = Frame(
            rgb=np.full((camera.height, camera.width, 3), 128, np.uint8),
            labels=labels,
            depth=np.full((camera.height, camera.width), 0.5, np.float32),
        )
        view = View(frame=f"r1_{k:03d}", camera=camera, world_T_camera=world_T_camera, images=images)
        recon.integrate(view)
    result = recon.result()
    merged = recon.merged()
    caps = spec.capabilities
    assert {ALL, "leaf", "stem"} <= set(merged), f"merged clouds {sorted(merged)}"
    for where, clouds in [("merged", merged)] + ([("result", result.clouds)] if caps.clouds else []):
        for name in (ALL, "leaf", "stem"):
            pts = clouds[name].points
            assert len(pts) > 100, f"{where} {name}: {len(pts)} points"
            assert np.max(np.abs(pts[:, 2] - plane_z)) < 0.003, f"{where} {name}: points off the plane z = {plane_z} m"
    assert _labels_on_their_halves(merged), "labels landed on the wrong halves of the plane"
    if caps.meshes:
        for name in (ALL, "leaf", "stem"):
            mesh = result.meshes[name]
            assert len(mesh.triangles) > 0, f"mesh {name} is empty"
            assert np.max(np.abs(mesh.vertices[:, 2] - plane_z)) < 0.01, f"mesh {name} off the plane"


def _labels_on_their_halves(clouds: dict[str, Any]) -> bool:
    """Leaf points at x < 0 and stem points at x > 0, up to a voxel or two."""
    return bool(clouds["leaf"].points[:, 0].max() < 0.003 and clouds["stem"].points[:, 0].min() > -0.003)


# ------------------------------------------------------------------------------- plants


def check_plant(registry: Registry, spec: BackendSpec, options: Any) -> None:
    """Grows a valid plant: a mesh with labels from its own table (background 0), leaf
    instances where declared, inside the plant-fit cylinder, the same for the same seed."""
    species = registry.build("plant", spec, options)
    plant = species.build(0)
    assert isinstance(plant, Plant), f"build() returned {type(plant).__name__}"
    mesh = plant.mesh
    assert len(mesh.faces) > 0 and np.all(np.isfinite(mesh.vertices))
    table = {lab.id for lab in plant.labels.labels}
    assert 0 in table and len(table) >= 2, "the label table needs background 0 and a plant label"
    used = {m.label for m in mesh.materials if m.labels is None}
    for m in mesh.materials:
        if m.labels is not None:
            used |= set(np.unique(m.labels).tolist())
    assert used <= table, f"materials use label ids {sorted(used - table)} outside the table"
    radius = np.linalg.norm(mesh.vertices[:, :2], axis=1).max()
    assert radius <= PLANT_FIT_RADIUS + 1e-6 and mesh.vertices[:, 2].max() <= PLANT_FIT_HEIGHT + 1e-6, (
        f"the plant ({radius:.3f} m wide, {mesh.vertices[:, 2].max():.3f} m high) leaves the plant-fit cylinder"
    )
    again = species.build(0).mesh
    assert np.array_equal(again.vertices, mesh.vertices), "the same seed grew another plant"


# ------------------------------------------------------------------------------- exporters


def _tree(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (relative path -> contents), folders as empty entries."""
    return {p.relative_to(root).as_posix(): (p.read_bytes() if p.is_file() else b"") for p in root.rglob("*")}


def check_exporter(registry: Registry, spec: BackendSpec, options: Any) -> None:
    """Its default output lies inside the run directory, and what is not a complete run is
    refused before anything is written, with a one-line :class:`UserError`: a path that does
    not exist, a folder that holds no run, a run still running."""
    exporter = registry.build("exporter", spec, options)
    default = Path(exporter.default_out)
    assert default.parts and not default.is_absolute() and ".." not in default.parts, (
        f"default_out {exporter.default_out!r} must be a path inside the run directory"
    )
    with tempfile.TemporaryDirectory(prefix="agrisim-exporter-") as tmp:
        root = Path(tmp)
        (root / "empty").mkdir()
        running = root / "running"
        running.mkdir()
        labels = [{"id": 0, "name": "background", "color": [0, 0, 0]}, {"id": 1, "name": "plant", "color": [0, 200, 0]}]
        run = {"status": "running", "frames_complete": [], "labels": labels, "config": {}, "results": []}
        (running / "run.json").write_text(json.dumps(run))
        K = [[100.0, 0.0, 31.5], [0.0, 100.0, 23.5], [0.0, 0.0, 1.0]]
        (running / "cameras.json").write_text(
            json.dumps({"intrinsics": {"K": K, "width": 64, "height": 48}, "frames": {}})
        )
        cases = {
            "a path that does not exist": root / "nowhere",
            "a folder without a run": root / "empty",
            "a run still running": running,
        }
        for what, run_dir in cases.items():
            before = _tree(root)
            try:
                exporter.export(run_dir, run_dir / default, False, None)
            except UserError as exc:
                message = str(exc)
                assert message.strip() and "\n" not in message.strip(), (
                    f"{what}: the refusal is not one line: {message!r}"
                )
            except Exception as exc:
                raise AssertionError(f"{what}: raised {type(exc).__name__} ({exc}), not a UserError") from exc
            else:
                raise AssertionError(f"{what}: exported it instead of refusing")
            after = _tree(root)
            changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
            assert not changed, f"{what}: refused, but wrote {changed}"


CHECKS: dict[str, Callable[[Registry, BackendSpec, Any], None]] = {
    "physics": check_physics,
    "planner": check_planner,
    "renderer": check_renderer,
    "sensor": check_sensor,
    "imager": check_imager,
    "reconstructor": check_reconstructor,
    "plant": check_plant,
    "room": check_room,
    "rig": check_rig,
    "poses": check_poses,
    "exporter": check_exporter,
    "format": check_format,
}
assert set(CHECKS) <= set(KINDS)

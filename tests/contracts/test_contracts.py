"""The contract suite: every registered backend of each kind keeps its kind's contract
(:mod:`agrisim.testing.contracts`), the built-ins and any installed plugin alike."""

from __future__ import annotations

import numpy as np
import pytest

from agrisim.registry import Registry, make_plugin_manager
from agrisim.testing.contracts import CHECKS, check

REGISTRY = Registry(make_plugin_manager())

#: every plant source: the procedural species, and Helios crops when the extra is installed
#: (two of its 31 models: each grows for about a second)
PLANTS = [n for n in REGISTRY.specs("plant") if not n.startswith("helios:")] + [
    n for n in ("helios:bean", "helios:strawberry") if n in REGISTRY.specs("plant")
]

CASES = [(kind, name) for kind in CHECKS if kind != "plant" for name in REGISTRY.specs(kind)]
CASES += [("plant", name) for name in PLANTS]


def test_every_kind_with_backends_is_covered() -> None:
    for kind in CHECKS:
        assert [name for k, name in CASES if k == kind], f"no {kind} backend to check"


@pytest.mark.parametrize(("kind", "name"), CASES, ids=[f"{k}-{n}" for k, n in CASES])
def test_backend_keeps_its_contract(kind: str, name: str) -> None:
    caps = REGISTRY.get(kind, name).capabilities
    if getattr(caps, "needs_cuda", False):
        from agrisim.capabilities import cuda_usable

        why = cuda_usable()
        if why is not None:
            pytest.skip(f"{name} needs a CUDA GPU ({why})")
    check(kind, name, REGISTRY)


# ------------------------------------------------------------- the contracts catch breakage


def _broken(kind: str, name: str, wrap) -> None:
    """Run ``kind``'s contract on backend ``name`` with its factory's result passed through
    ``wrap``, which breaks it in one way."""
    import dataclasses

    from agrisim.testing.contracts import CHECKS

    spec = REGISTRY.get(kind, name)
    broken = dataclasses.replace(spec, factory=lambda *args: wrap(spec.factory(*args)))
    CHECKS[kind](REGISTRY, broken, spec.options_model())


def test_a_renderer_with_depth_2_percent_long_breaks_its_contract() -> None:
    def wrap(renderer):
        render = renderer.render

        def longer(*args):
            frame = render(*args)
            frame.depth = frame.depth * np.float32(1.02)
            return frame

        renderer.render = longer
        return renderer

    with pytest.raises(AssertionError, match="depth"):
        _broken("renderer", "raycast", wrap)


def test_a_sensor_4_percent_long_breaks_its_contract() -> None:
    def wrap(sensor):
        measure = sensor.measure

        def longer(*args):
            return measure(*args) * np.float32(1.04)

        sensor.measure = longer
        return sensor

    with pytest.raises(AssertionError, match="off its exact depth"):
        _broken("sensor", "azure-kinect-nfov", wrap)


def test_an_imager_whose_noise_ignores_the_seed_breaks_its_contract() -> None:
    draws = iter(range(1, 1000))

    def wrap(imager):
        imager.seed = next(draws)  # (each imager built gets other noise than the run's seed says)
        return imager

    with pytest.raises(AssertionError, match="other bytes"):
        _broken("imager", "imx708", wrap)


def test_a_room_that_floats_the_plant_breaks_its_contract() -> None:
    def wrap(room):
        scene = room.scene

        def lifted(plant, **kw):
            drawn = scene(plant, **kw)
            m = drawn.mesh(drawn.plant)
            m.vertices = m.vertices + np.array([0.0, 0.0, 0.01])  # a centimetre above the soil
            return drawn

        room.scene = lifted
        return room

    with pytest.raises(AssertionError, match="not on the soil"):
        _broken("room", "lab", wrap)


def test_a_rig_whose_cameras_look_away_breaks_its_contract() -> None:
    import dataclasses

    turn = np.diag([-1.0, 1.0, -1.0, 1.0])  # half a turn about each camera's own y axis

    def wrap(rig):
        setpoints = rig.setpoints

        def away(cell, routine):
            sps = setpoints(cell, routine)
            return {
                arm: [dataclasses.replace(sp, world_T_camera=sp.world_T_camera @ turn) for sp in s]
                for arm, s in sps.items()
            }

        rig.setpoints = away
        return rig

    with pytest.raises(AssertionError, match="does not look at the plant"):
        _broken("rig", "paper", wrap)


def test_a_pose_source_that_answers_for_a_run_it_never_saw_breaks_its_contract() -> None:
    def wrap(source):
        source.poses = lambda run_dir: {}
        return source

    with pytest.raises(AssertionError, match="no views"):
        _broken("poses", "colmap", wrap)


def test_a_format_that_swallows_a_bad_file_breaks_its_contract() -> None:
    def wrap(reader):
        read = reader.read

        def lenient(path, settings, **kw):
            try:
                return read(path, settings, **kw)
            except Exception:  # noqa: BLE001 - the breakage under test
                return None  # as if an unreadable file were an empty plant

        reader.read = lenient
        return reader

    with pytest.raises(AssertionError, match="holds no plant"):
        _broken("format", "gltf", wrap)


def test_a_planner_that_ignores_collisions_breaks_its_contract() -> None:
    def wrap(planner):
        planner.plan = lambda start, goal, *rest: np.array([start, goal])
        return planner

    with pytest.raises(AssertionError, match="wall"):
        _broken("planner", "ompl", wrap)


def test_a_reconstructor_in_camera_coordinates_breaks_its_contract() -> None:
    def wrap(recon):
        integrate = recon.integrate

        def camera_frame(view):
            view.world_T_camera = np.eye(4)
            return integrate(view)

        recon.integrate = camera_frame
        return recon

    with pytest.raises(AssertionError, match="off the plane"):
        _broken("reconstructor", "pointcloud", wrap)


def test_an_exporter_that_writes_before_it_checks_breaks_its_contract() -> None:
    def wrap(exporter):
        export = exporter.export

        def eager(run_dir, out, *rest):
            out.parent.mkdir(parents=True, exist_ok=True)
            out.write_text("{}")  # a half-made export left behind by a refusal
            return export(run_dir, out, *rest)

        exporter.export = eager
        return exporter

    with pytest.raises(AssertionError, match="refused, but wrote"):
        _broken("exporter", "coco", wrap)


def test_an_exporter_that_refuses_with_a_traceback_breaks_its_contract() -> None:
    def wrap(exporter):
        def crash(run_dir, *rest):
            return (run_dir / "run.json").read_text()  # FileNotFoundError, not a one-line refusal

        exporter.export = crash
        return exporter

    with pytest.raises(AssertionError, match="not a UserError"):
        _broken("exporter", "rosbag", wrap)

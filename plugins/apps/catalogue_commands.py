"""The commands that describe what is installed and what a plant is: ``plants``, ``traits``,
``plugins`` and ``doctor``. Each is a :class:`~agrisim.commands.Command`, its flags and the
function of its parsed flags, registered by :mod:`agrisim.plugins.apps.commands`."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from agrisim.commands import Command
from agrisim.config import RunConfig, build_config
from agrisim.errors import UserError
from agrisim.files import layout

if TYPE_CHECKING:
    from agrisim.registry import Registry


def _plants_arguments(plants: argparse.ArgumentParser) -> None:
    plants.add_argument("--seed", type=int, default=0, metavar="N", help="seed to grow each species with (0)")


def _traits_arguments(traits: argparse.ArgumentParser) -> None:
    traits.add_argument(
        "target",
        metavar="PLANT|RUN",
        help="a species (agrisim plants), a plant file (its leaves: its instances, else its connected pieces), or a run's directory",
    )
    traits.add_argument(
        "--seed", type=int, default=None, metavar="N", help="seed to grow a species with (0; a run's own for a run)"
    )
    traits.add_argument(
        "--out", type=Path, default=None, help="traits.json's path (default: RUN/traits.json, or ./traits.json)"
    )
    traits.add_argument("--overwrite", action="store_true", help="replace an existing traits.json")
    traits.add_argument(
        "--measure",
        action="store_true",
        help="also measure the traits from the run's views, as a phenotyping pipeline would, and score them "
        'against the truth (traits.json\'s "measured")',
    )
    traits.add_argument(
        "--depth",
        choices=["sensor", "truth"],
        default="sensor",
        help="with --measure: the run's depth sensor (its exact depth where it had none; default) or the exact depth",
    )


def _plugins_arguments(plugins: argparse.ArgumentParser) -> None:
    plugins.add_argument("--options", action="store_true", help="also list each backend's options")


def _doctor_arguments(doctor: argparse.ArgumentParser) -> None:
    doctor.add_argument("--json", action="store_true", help="write the same facts as JSON to stdout")
    doctor.add_argument("--no-timing", action="store_true", help="skip the two timings (a few seconds)")


def _cmd_plugins(args: argparse.Namespace) -> int:
    from agrisim.capabilities import describe
    from agrisim.registry import PROVIDER_HOOKS, Registry, make_plugin_manager

    registry = Registry(make_plugin_manager())
    for kind in PROVIDER_HOOKS:
        specs = registry.specs(kind)
        print(f"{kind}:")
        if not specs:
            print("  (none installed)")
        width = max((len(n) for n in specs), default=0)
        for name, spec in specs.items():
            print(f"  {name:<{width}}  {spec.description}  [{spec.distribution}]")
            if spec.limits:
                print(f"  {'':<{width}}  limits: {spec.limits}")
            if spec.capabilities is not None:
                print(f"  {'':<{width}}  can: {describe(spec.capabilities)}")
            if args.options:
                for field, info in spec.options_model.model_fields.items():
                    doc = (info.description or "").replace("\n", " ")
                    print(f"  {'':<{width}}    {kind}.{name}.{field} = {info.default!r}  {doc}")
    return 0


def _cmd_doctor(args: argparse.Namespace) -> int:
    import json

    from agrisim.plugins.apps.doctor import gather
    from agrisim.plugins.apps.doctor_report import render_text

    report = gather(timing=not args.no_timing)
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        for line in render_text(report):
            print(line)
    return 0 if report["default_run"]["ok"] else 1


def _cmd_plants(args: argparse.Namespace) -> int:
    from agrisim.registry import Registry, make_plugin_manager
    from agrisim.scene.plant_cache import grown
    from agrisim.scene.texturing import surface_summary

    if args.seed < 0:
        raise UserError(f"--seed must be 0 or more, got {args.seed}")
    registry = Registry(make_plugin_manager())
    specs = registry.specs("plant")
    if not specs:
        print("no plant species installed")
        return 0
    width = max(len(n) for n in specs)
    print(
        f"{'species':<{width}}  {'triangles':>9}  {'cut away':>8}  {'leaves':>6}  {'leaf cm^2':>9}  labels  [distribution]"
    )
    for name, spec in specs.items():
        options = spec.options_model()
        plant = grown(name, options, args.seed, registry.build("plant", spec, options).build)
        organs = ", ".join(lab.name for lab in plant.labels.labels if lab.id)
        cut, leaves, leaf_area = surface_summary(plant.mesh, samples=100_000)
        print(
            f"{name:<{width}}  {len(plant.mesh.faces):>9,}  {cut:>7.1%}  {leaves:>6}  {leaf_area * 1e4:>9.0f}  "
            f"{organs}  [{spec.distribution}]"
        )
    print("cut away: share of the plant's surface area that opacity removes (what RepOpa labels wrongly)")
    print("leaves: leaf instances; leaf cm^2: their opaque area, sampled (agrisim traits SPECIES: exact, leaf by leaf)")
    return 0


def _cmd_traits(args: argparse.Namespace) -> int:
    from pathlib import Path

    from agrisim.errors import OutputError
    from agrisim.files.atomic import write_json
    from agrisim.files.rundir import read_json
    from agrisim.plant_choice import check_plant_name, resolve_plant
    from agrisim.plugins.apps.progress import EpisodeProgress
    from agrisim.plugins.apps.traits.document import traits_document
    from agrisim.plugins.apps.traits.estimate import measurable_frames, measure
    from agrisim.plugins.apps.traits.truth import plant_traits
    from agrisim.registry import Registry, make_plugin_manager

    target = Path(args.target)
    if args.seed is not None and args.seed < 0:
        raise UserError(f"--seed must be 0 or more, got {args.seed}")
    registry = Registry(make_plugin_manager())
    if target.is_dir():
        run = read_json(target / layout.RUN_JSON, "not an agrisim run (no run.json)")
        if args.seed is not None:
            raise UserError("--seed applies to a species, not to a run (a run's plant has the run's seed)")
        config = build_config(run["config"])
        out = args.out or target / "traits.json"
        if args.measure and config.bench is not None:
            raise UserError(
                "--measure measures one plant from a run's views; a bench's plants are not measured apart yet "
                f"(agrisim traits {target} gives each plant's exact traits)"
            )
        if args.measure:
            measurable_frames(target, run)
    else:
        if args.measure:
            raise UserError(f"--measure needs a run's directory (its views), got {args.target!r}")
        config = build_config({"plant": args.target, "seed": 0 if args.seed is None else args.seed})
        out = args.out or Path("traits.json")
    check_plant_name(registry, config)
    if out.exists() and not args.overwrite:
        raise OutputError(f"{out} already exists; pass --overwrite to replace it")
    if config.bench is not None:
        return _bench_traits(registry, config, out)
    plant = resolve_plant(registry, config)
    with EpisodeProgress("triangles") as progress:
        truth = plant_traits(plant, progress.update)
        measured = None
        if args.measure:
            measured = measure(target, args.depth, lambda done, total: progress.stage("views", done, total))
    doc = traits_document(plant, config.seed, truth, measured)
    write_json(out, doc)
    p = doc["plant"]
    print(
        f"{plant.name}: {p['leaf_count']} leaves, {p['leaf_area_m2'] * 1e4:.1f} cm^2 of leaf; "
        f"height {p['height_m'] * 100:.1f} cm, crown {p['crown_diameter_m'] * 100:.1f} cm, "
        f"hull {p['convex_hull_volume_m3'] * 1e3:.2f} L, projected {p['projected_area_m2'] * 1e4:.1f} cm^2; "
        f"mean leaf inclination {p['mean_inclination_deg']:.1f} deg ({p['de_wit_class']})"
    )
    found = {leaf.id: leaf for leaf in measured.leaves} if measured is not None else {}
    if measured is not None:
        e = doc["measured"]["errors"]
        print(
            f"measured from {measured.views} views ({measured.depth} depth): {e['leaves_seen']} of "
            f"{e['leaves_there']} leaves seen, {e['clusters']} clusters without instances "
            f"({e['clusters_one_leaf']} one leaf each); leaf area MAPE {e['area_mape_pct']:.1f}%, "
            f"inclination error {e['inclination_error_mean_deg']:.1f} deg; "
            f"height {measured.height_m * 100:.1f} cm ({e['height_error_m'] * 1e3:+.1f} mm), "
            f"hull {measured.convex_hull_volume_m3 * 1e3:.2f} L ({e['hull_volume_error_pct']:+.1f}%)"
        )
    leaves = doc["leaves"]
    extra = f"  {'measured':>8}  {'meas deg':>8}" if measured is not None else ""
    print(f"{'leaf':>5}  {'area cm^2':>9}  {'length cm':>9}  {'width cm':>8}  {'incl deg':>8}  {'azimuth':>7}{extra}")
    for leaf in leaves[:20]:
        seen = found.get(leaf["id"])
        cells = f"  {seen.area_m2 * 1e4:>8.2f}  {seen.inclination_deg:>8.1f}" if seen is not None else ""
        print(
            f"{leaf['id']:>5}  {leaf['area_m2'] * 1e4:>9.2f}  {leaf['length_m'] * 100:>9.2f}  "
            f"{leaf['width_m'] * 100:>8.2f}  {leaf['inclination_deg']:>8.1f}  {leaf['azimuth_deg']:>7.1f}{cells}"
        )
    if len(leaves) > 20:
        print(f"  ... {len(leaves) - 20} more in {out}")
    print(f"wrote {out}")
    return 0


def _bench_traits(registry: Registry, config: RunConfig, out: Path) -> int:
    """A bench's traits: one row a plant, each grown alone (:mod:`.traits.bench`)."""
    from agrisim.files.atomic import write_json
    from agrisim.plugins.apps.progress import EpisodeProgress
    from agrisim.plugins.apps.traits.bench import bench_document, bench_traits, print_bench

    with EpisodeProgress("triangles") as progress:
        rows = bench_traits(registry, config, lambda plant, done, total: progress.stage(plant, done, total))
    write_json(out, bench_document(rows))
    print_bench(rows)
    print(f"wrote {out}")
    return 0


#: this module's commands, each its flags and its function
COMMANDS = [
    Command(
        "plants",
        help="list the plant species: triangles, organs, area cut away by opacity",
        add_arguments=_plants_arguments,
        run=_cmd_plants,
    ),
    Command(
        "traits",
        help="a plant's traits, exact from its model: leaf by leaf, and the whole plant's",
        description="Measure a plant's traits exactly from its model: each leaf's area (its opaque texels), midrib "
        "length, width, inclination, azimuth, attachment and centroid; the plant's leaf count and area, height, crown "
        "diameter, convex-hull volume, projected area and leaf angle distribution (nearest de Wit class). Prints "
        "them and writes traits.json (RUN/traits.json for a run); with --measure, a run's traits are also measured "
        "from its views and scored against the truth. Definitions and units: docs/traits.md.",
        add_arguments=_traits_arguments,
        run=_cmd_traits,
    ),
    Command(
        "plugins",
        help="list every backend of every kind and where it comes from",
        add_arguments=_plugins_arguments,
        run=_cmd_plugins,
    ),
    Command(
        "doctor",
        help="what this machine can run: CPU, libLLVM, GPUs, ROS, every backend, speed against the README's",
        description="Report what this machine can run: Python, the CPU's vector instructions, the libLLVM Dr.Jit "
        "loaded, CUDA for Mitsuba and PyTorch, ROS 1, Cyclone DDS, the tests' browser, every backend (and why "
        "not), and one 1080p raycast view and the IK timed against the README's figures. Exit status 1 when "
        "agrisim run with its defaults cannot work here.",
        add_arguments=_doctor_arguments,
        run=_cmd_doctor,
    ),
]

"""A bench of plants (``[bench]``, ``--bench RxC --spacing M``): where each plant's pot stands,
the rig's cell with a pot and a keep-out for each, and the plants joined into the one plant a
room draws, each plant's faces a range of it (:class:`~agrisim.scene.model.BenchPlant`)."""

from __future__ import annotations

import dataclasses
from itertools import combinations

import numpy as np

from agrisim.config import RunConfig, parse_grid
from agrisim.errors import UserError
from agrisim.robot.cell import Box, Cell, Cylinder
from agrisim.scene.model import BenchPlant, Label, LabelTable, Mesh, Plant
from agrisim.scene.transforms import translation


def bench_layout(config: RunConfig) -> list[BenchPlant]:
    """The plants of ``config.bench`` in bench order (a grid row by row along x, rows along y),
    named ``plant_01``...; a plant with no seed of its own grows the run's plant's seed
    (``--plant-seed``, else ``--seed``) plus its index."""
    bench = config.bench
    assert bench is not None
    first_seed = int(config.plants.get(config.plant, {}).get("seed", config.seed))  # (checked by check_run)
    if bench.grid is not None:
        rows, cols = parse_grid(bench.grid, "bench")
        spots: list[tuple[str, int | None, float, float]] = [
            (config.plant, None, (c - (cols - 1) / 2) * bench.spacing, (r - (rows - 1) / 2) * bench.spacing)
            for r in range(rows)
            for c in range(cols)
        ]
    else:
        spots = [(p.plant or config.plant, p.seed, p.x, p.y) for p in bench.plants]
    plants = [
        BenchPlant(f"plant_{k + 1:02d}", name, first_seed + k if seed is None else seed, (float(x), float(y)))
        for k, (name, seed, x, y) in enumerate(spots)
    ]
    gap = 2 * config.cell.pot_radius
    for a, b in combinations(plants, 2):
        d = float(np.hypot(a.xy[0] - b.xy[0], a.xy[1] - b.xy[1]))
        if d < gap:
            raise UserError(
                f"bench: {a.name} and {b.name} overlap: their pots stand {d:.3f} m apart, less than two pot radii "
                f"({gap:g} m); space them further (--spacing, or [[bench.plants]] x and y)"
            )
    return plants


def bench_cell(cell: Cell, plants: list[BenchPlant], rig: str) -> Cell:
    """``cell`` with its pot and keep-out repeated at each plant's place (``pot_01``,
    ``plant_keepout_01``...) and its table grown to hold them all, with the margin it had."""
    by_name = {ob.name: ob for ob in cell.obstacles}
    pot, table = by_name.get("pot"), by_name.get("table")
    if not isinstance(pot, Cylinder) or not isinstance(table, Box):
        raise UserError(f"rig {rig!r} holds one plant: its cell has no pot on a table to make a bench of")
    xy = np.array([p.xy for p in plants])
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    mid = np.append((lo + hi) / 2, 0.0)
    size = (table.size[0] + hi[0] - lo[0], table.size[1] + hi[1] - lo[1], table.size[2])
    grown = Box("table", size, translation(*mid) @ table.world_T)
    reach = _footprint(grown)
    for ob in cell.obstacles:
        (lo_ob, hi_ob), own = _footprint(ob), ob.name in ("floor", "table", "pot", "plant_keepout")
        if not own and (lo_ob < reach[1]).all() and (hi_ob > reach[0]).all():
            raise UserError(
                f"bench: its table ({size[0]:.2f} x {size[1]:.2f} m) would reach the rig's {ob.name}; "
                "use a smaller --spacing or fewer plants"
            )
    obstacles = [grown if ob is table else ob for ob in cell.obstacles if ob.name not in ("pot", "plant_keepout")]
    for p in plants:
        at = translation(p.xy[0], p.xy[1], 0.0)
        index = p.name.removeprefix("plant")
        for each in (pot, by_name.get("plant_keepout")):
            if each is not None:
                obstacles.append(dataclasses.replace(each, name=each.name + index, world_T=at @ each.world_T))
    return dataclasses.replace(cell, obstacles=tuple(obstacles), bench=tuple(plants))


def _footprint(ob: Box | Cylinder) -> tuple[np.ndarray, np.ndarray]:
    """The corners (x, y) of the box on the floor that holds ``ob``'s outline."""
    c = ob.world_T[:2, 3]
    if isinstance(ob, Cylinder):
        return c - ob.radius, c + ob.radius
    half = np.abs(ob.world_T[:2, :2]) @ np.array(ob.size[:2]) / 2
    return c - half, c + half


def join_plants(plants: list[Plant], bench: list[BenchPlant]) -> Plant:
    """One plant of ``plants``, each moved to its place on the bench (its frame's origin, the
    soil's centre, ``xy`` from the bench's): labels merged by name (the first plant's ids kept),
    leaf instances numbered on across the bench, each plant's faces the range its
    :class:`BenchPlant` gives."""
    if any(p.points is not None for p in plants):
        raise UserError("bench: plants are drawn as meshes; a point cloud or --as-points holds one plant")
    labels = list(plants[0].labels.labels)
    meshes, instances, placed, faces, leaves = [], [], [], 0, 0
    for plant, slot in zip(plants, bench, strict=True):
        lut = np.zeros(256, np.uint8)
        for lab in plant.labels.labels:
            known = next((m for m in labels if m.name == lab.name), None)
            if known is None:
                known = Label(max(m.id for m in labels) + 1, lab.name, lab.color)
                labels.append(known)
            lut[lab.id] = known.id
        m = plant.mesh
        materials = [
            dataclasses.replace(x, labels=None if x.labels is None else lut[x.labels], label=int(lut[x.label]))
            for x in m.materials
        ]
        inst = None if m.face_instance is None else m.face_instance.astype(np.int64)
        if inst is not None:
            inst[inst > 0] += leaves
        meshes.append(dataclasses.replace(m.transformed(translation(*slot.xy, 0.0)), materials=materials))
        instances.append(inst)
        placed.append(dataclasses.replace(slot, faces=(faces, faces + len(m.faces))))
        faces += len(m.faces)
        leaves = max(leaves, 0 if inst is None or not len(inst) else int(inst.max()))
    if leaves > np.iinfo(np.uint16).max:
        raise UserError(f"bench: {leaves} leaves, more than the instance masks hold (65535)")
    base = np.cumsum([0] + [len(m.vertices) for m in meshes])
    mat_base = np.cumsum([0] + [len(m.materials) for m in meshes])
    cat = np.concatenate
    mesh = Mesh(
        meshes[0].name,
        cat([m.vertices for m in meshes]),
        cat([m.faces + base[i] for i, m in enumerate(meshes)]),
        [x for m in meshes for x in m.materials],
        cat([m.face_material + mat_base[i] for i, m in enumerate(meshes)]),
        None if all(m.uvs is None for m in meshes) else cat([_or(m.uvs, (len(m.vertices), 2), 0.0) for m in meshes]),
        None
        if all(i is None for i in instances)
        else cat([_or(i, (len(m.faces),), 0) for i, m in zip(instances, meshes, strict=True)]),
        None
        if all(m.colors is None for m in meshes)
        else cat([_or(m.colors, (len(m.vertices), 3), 1.0) for m in meshes]),
    )
    notes = list(dict.fromkeys(n for p in plants for n in p.notes))
    name = f"bench of {len(plants)}: " + ", ".join(dict.fromkeys(p.name for p in plants))
    return Plant(name, mesh, LabelTable(labels), any(p.organs for p in plants), plants[0].seed, notes, bench=placed)


def _or(a: np.ndarray | None, shape: tuple[int, ...], fill: float) -> np.ndarray:
    return a if a is not None else np.full(shape, fill)

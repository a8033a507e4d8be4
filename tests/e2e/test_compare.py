"""``agrisim compare``: the paper's Table 2 from episodes run as Ray tasks.

The table logic (percentages, rows, markdown, CSV) is checked on small metrics dictionaries
whose expected numbers the tests compute themselves. The end-to-end part runs two plants in
both modes at a tiny size on the local Ray that compare starts with two workers (about 15 s,
mostly Ray and worker start-up), then one plant again with one worker, and checks that the
episodes ran as Ray tasks in other processes, that the table's rows are the run directories'
``metrics.json`` figures, and that the worker count changes nothing. That second compare and
Table 3's run on one Ray the module starts afterwards (``shared_ray``), which compare uses as it
finds it. Full-size timing lives in ``bench/compare_plants.py``.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import local_ray

from agrisim.app.cli import main
from agrisim.config import first_difference
from agrisim.errors import UserError
from agrisim.plugins.apps import compare as cmp

TINY = [
    "--physics",
    "kinematic",
    "--setpoints",
    "1x2",
    "--resolution",
    "160x90",
    "--shadow-samples",
    "0",
    "--set",
    "metrics.truth_samples=20000",
]
PLANTS = ("bog_marshcress", "basket_grass")


# ------------------------------------------------------------------ table logic on made-up metrics


def _label(pixels: int, points: int, p: float, chamfer: float) -> dict[str, Any]:
    per = {"1": p / 2, "2": p, "5": min(1.0, p * 1.5)}
    return {
        "pixels": pixels,
        "points": points,
        "precision": per,
        "recall": {k: v / 3 for k, v in per.items()},
        "recall_visible": {k: v / 2 for k, v in per.items()},
        "fscore": {k: v / 4 for k, v in per.items()},
        "chamfer_mm": chamfer,
    }


def _metrics(plant: str, mode: str, pixels: int, points: int, p: float, chamfer: float, organs: bool = False) -> dict:
    labels = {"all": _label(pixels, points, p, chamfer)}
    if organs:
        labels = {"leaf": _label(pixels - 10, points - 5, p, chamfer), "stem": _label(10, 5, p, chamfer), **labels}
    else:
        labels = {"plant": _label(pixels, points, p, chamfer), **labels}
    return {
        "plant": plant,
        "seg_mode": mode,
        "recon": "pointcloud",
        "frames": 100,
        "thresholds_mm": [1.0, 2.0, 5.0],
        "labels": labels,
        "leaf_instances_seen": None,
    }


@pytest.fixture
def made_up() -> dict[tuple[str, str], dict | None]:
    return {
        ("hydrangea", "texture"): _metrics("hydrangea", "texture", 24_224_000, 686_045, 0.9, 1.5, organs=True),
        ("hydrangea", "repopa"): _metrics("hydrangea", "repopa", 24_990_000, 851_382, 0.7, 3.25, organs=True),
        ("boxwood", "texture"): _metrics("boxwood", "texture", 14_629_000, 810_085, 0.95, 1.0),
        ("boxwood", "repopa"): None,  # a run that did not finish
    }


def test_percent_is_the_papers_formula() -> None:
    # Table 2's Hydrangea row: 24.224 -> 24.990 (10^6 pixels) is 3.16 %, 686045 -> 851382 points 24.10 %
    assert round(cmp.percent_increase(24.224, 24.990), 2) == 3.16
    assert round(cmp.percent_increase(686045, 851382), 2) == 24.10
    assert cmp.percent_increase(0, 5) is None
    assert cmp.percent_increase(None, 5) is None
    assert cmp.percent_increase(5, None) is None


def test_rows_from_metrics(made_up) -> None:
    rows = cmp.table_rows(made_up, ["hydrangea", "boxwood"], per_label=True)
    assert [(r["plant"], r["label"]) for r in rows] == [
        ("hydrangea", "all"),
        ("hydrangea", "leaf"),
        ("hydrangea", "stem"),
        ("boxwood", "all"),
    ]
    h = rows[0]
    assert h["pixels"] == {"texture": 24_224_000, "repopa": 24_990_000}
    assert h["pixels_pct"] == pytest.approx(100 * (24_990_000 / 24_224_000 - 1))
    assert h["points_pct"] == pytest.approx(100 * (851_382 / 686_045 - 1))
    assert h["precision"]["repopa"]["2"] == 0.7
    assert h["chamfer_mm"] == {"texture": 1.5, "repopa": 3.25}
    b = rows[-1]
    assert b["pixels"] == {"texture": 14_629_000, "repopa": None}
    assert b["pixels_pct"] is None and b["points_pct"] is None
    # a single "plant" label would only repeat "all": no extra rows for it
    assert [r["label"] for r in cmp.table_rows(made_up, ["boxwood"], per_label=True)] == ["all"]


def test_markdown_table(made_up) -> None:
    rows = cmp.table_rows(made_up, ["hydrangea", "boxwood"], per_label=True)
    md = cmp.markdown_table(rows).splitlines()
    head = [c.strip() for c in md[0].strip("|").split("|")]
    assert head[:8] == [
        "Plant",
        "Pixels (10^6) Ours",
        "Pixels (10^6) RepOpa",
        "%",
        "Points Ours",
        "Points RepOpa",
        "%",
        "Precision@2mm Ours",
    ]
    assert len(md) == 2 + 2  # header, rule, one row per plant (organ rows only in the CSV)
    cells = [c.strip() for c in md[2].strip("|").split("|")]
    assert cells[:7] == ["Hydrangea", "24.224", "24.990", "3.16", "686045", "851382", "24.10"]
    assert cells[head.index("Precision@2mm RepOpa")] == "0.700"
    assert cells[head.index("Chamfer (mm) RepOpa")] == "3.25"
    missing = [c.strip() for c in md[3].strip("|").split("|")]
    assert missing[:4] == ["Boxwood", "14.629", "–", "–"]


def test_csv_table(made_up) -> None:
    rows = cmp.table_rows(made_up, ["hydrangea", "boxwood"], per_label=True)
    table = list(csv.DictReader(io.StringIO(cmp.csv_table(rows))))
    assert [(r["plant"], r["label"]) for r in table] == [(r["plant"], r["label"]) for r in rows]
    h = table[0]
    assert int(h["pixels_texture"]) == 24_224_000 and int(h["points_repopa"]) == 851_382
    assert float(h["pixels_pct"]) == 100 * (24_990_000 / 24_224_000 - 1)  # exact: repr floats
    assert float(h["fscore_5mm_texture"]) == min(1.0, 0.9 * 1.5) / 4
    assert float(h["recall_visible_1mm_repopa"]) == 0.7 / 2 / 2
    assert h["frames_texture"] == "100"
    b = table[-1]
    assert b["pixels_repopa"] == "" and b["pixels_pct"] == ""


def test_chart_is_a_png(made_up) -> None:
    png = cmp.chart_png(cmp.table_rows(made_up, ["hydrangea", "boxwood"]))
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_names_and_differences() -> None:
    assert cmp.parse_names(None, "plants") is None
    assert cmp.parse_names(" a, b ", "plants") == ["a", "b"]
    for bad in ("a,,b", "a,a"):
        with pytest.raises(UserError):
            cmp.parse_names(bad, "plants")
    with pytest.raises(UserError, match="allowed: texture, repopa"):
        cmp.parse_names("texture,alpha", "seg-modes", cmp.SEG_MODES)
    assert first_difference({"a": {"b": 1, "c": 2}}, {"a": {"b": 1, "c": 2}}) is None
    assert first_difference({"a": {"b": 1}}, {"a": {"b": 2}}) == ("a.b", 1, 2)
    assert first_difference({"a": 1}, {"a": 1, "z": 0}) == ("z", None, 0)


def test_run_dir_states(tmp_path: Path) -> None:
    d = tmp_path / "run"
    assert cmp.run_dir_state(d) == "empty"
    d.mkdir()
    assert cmp.run_dir_state(d) == "empty"
    (d / "scene").mkdir()
    assert cmp.run_dir_state(d) == "partial"
    (d / "run.json").write_text(json.dumps({"status": "interrupted"}))
    assert cmp.run_dir_state(d) == "unfinished"
    (d / "run.json").write_text(json.dumps({"status": "complete"}))
    assert cmp.run_dir_state(d) == "complete-no-metrics"
    (d / "metrics.json").write_text("{}")
    assert cmp.run_dir_state(d) == "complete"


def test_plan_validates_before_anything(tmp_path: Path) -> None:
    plan = cmp.plan_compare({}, out=tmp_path / "c")
    assert plan.plants == cmp.PAPER_PLANTS and len(plan.episodes) == 20
    e = plan.episodes[1]
    assert (e.plant, e.seg_mode, e.run_dir) == ("hydrangea", "repopa", (tmp_path / "c" / "hydrangea" / "repopa"))
    assert e.config["render"]["seg_mode"] == "repopa" and e.config["sink"]["rerun"]["save"] is False
    assert e.config["output"]["out"] == str(e.run_dir)
    # flags for the episodes pass through; plant, seg mode and output are compare's own
    plan = cmp.plan_compare(
        {"plant": "boxwood", "seed": 7, "render": {"seg_mode": "repopa"}},
        out=tmp_path / "c",
        plants=["coltsfoot"],
        seg_modes=["texture"],
    )
    assert [(e.plant, e.seg_mode, e.config["seed"]) for e in plan.episodes] == [("coltsfoot", "texture", 7)]
    assert not (tmp_path / "c").exists()


def test_resume_plans_per_run_directory(tmp_path: Path) -> None:
    out = tmp_path / "c"
    fresh = cmp.plan_compare({}, out=out, plants=["boxwood", "coltsfoot"])
    by = {(e.plant, e.seg_mode): e for e in fresh.episodes}

    def saved(key: tuple[str, str], status: str, metrics: bool = False, **change: Any) -> None:
        e = by[key]
        e.run_dir.mkdir(parents=True)
        config = {**e.config, **change}
        (e.run_dir / "run.json").write_text(json.dumps({"status": status, "config": config}))
        if metrics:
            (e.run_dir / "metrics.json").write_text("{}")

    saved(("boxwood", "texture"), "complete", metrics=True)
    saved(("boxwood", "repopa"), "interrupted")
    (by[("coltsfoot", "texture")].run_dir / "scene").mkdir(parents=True)  # killed before run.json
    (out / "compare.json").write_text("{}")
    plan = cmp.plan_compare({}, out=out, plants=["boxwood", "coltsfoot"], resume=True)
    actions = {
        (e.plant, e.seg_mode): (e.action, e.config["output"]["resume"], e.config["output"]["overwrite"])
        for e in plan.episodes
    }
    assert actions == {
        ("boxwood", "texture"): ("skip", False, False),
        ("boxwood", "repopa"): ("resume", True, False),
        ("coltsfoot", "texture"): ("run", False, True),  # leftovers of nothing finished
        ("coltsfoot", "repopa"): ("run", False, False),
    }
    with pytest.raises(UserError, match="already exists; pass --overwrite"):
        cmp.plan_compare({}, out=out, plants=["boxwood"])
    with pytest.raises(UserError, match="was run with seed = 0, this compare asks for 5"):
        cmp.plan_compare({"seed": 5}, out=out, plants=["boxwood"], resume=True)
    (by[("boxwood", "texture")].run_dir / "metrics.json").unlink()
    with pytest.raises(UserError, match="complete run without metrics.json"):
        cmp.plan_compare({}, out=out, plants=["boxwood"], resume=True)


def test_a_failing_episode_is_recorded_not_raised(tmp_path: Path) -> None:
    garbage = tmp_path / "garbage.glb"
    garbage.write_bytes(b"not a glTF file")
    plan = cmp.plan_compare({}, out=tmp_path / "c", plants=[str(garbage)], seg_modes=["texture"])
    assert plan.episodes[0].run_dir == tmp_path / "c" / "garbage" / "texture"
    record = cmp.run_episode_task(plan.episodes[0].config)  # what each Ray task runs
    assert record["status"] == "error" and "garbage.glb" in record["error"]
    assert record["pid"] == os.getpid() and record["rss_peak_mb"] > 0


def _refuse_ray(**kwargs: Any) -> dict:
    raise AssertionError("Ray started")


@pytest.fixture
def no_ray(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if compare starts Ray: bad input must be found before that."""
    monkeypatch.setattr(cmp, "start_ray", _refuse_ray)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--plants", "boxwood,rose"], "unknown plant 'rose'; species: "),
        (["--seg-modes", "texture,alpha"], "--seg-modes: unknown 'alpha'"),
        (["--workers", "0"], "--workers must be 1 or more"),
        (["--physics", "nope"], "unknown physics backend 'nope'"),
        (["--renderer", "none"], "needs a renderer"),
        # TinyRenderer ignores opacity: its "texture" column would repeat RepOpa's without a word
        (["--renderer", "pybullet"], "renderer backend 'pybullet' cannot draw segmentation mode 'texture'"),
        (["--renderer", "pybullet", "--seg-modes", "repopa", "--labels", "organs"], "cannot draw organ labels"),
        (["--set", "output.rrd=x.rrd"], "--rrd ([sink.rerun] path) cannot be shared"),
        (["--overwrite", "--resume"], "exclude each other"),
        (["--ray-address", "127.0.0.1:1"], "--ray-address 127.0.0.1:1: cannot reach"),
        (["--point-sizes", "0.002"], "give --as-points N too"),
        (["--as-points", "100"], "needs --point-sizes"),
        (["--as-points", "100", "--point-sizes", "0.002,0"], "--point-sizes must be a finite number"),
        (["--as-points", "100", "--point-sizes", "0.002,big"], "comma-separated sizes in metres"),
        (["--as-points", "100", "--point-sizes", "0.002,0.002"], "more than once"),
        (["--as-points", "0", "--point-sizes", "0.002"], "--as-points must be a whole number"),
        (["--as-points", "100", "--point-sizes", "0.002", "--seg-modes", "repopa"], "leave out --seg-modes"),
        (["--as-points", "100", "--point-sizes", "0.002", "--renderer", "pybullet"], "cannot draw"),
    ],
)
def test_bad_input_exits_2_with_one_line(args, message, tmp_path, monkeypatch, cli) -> None:
    if "--ray-address" not in args:
        monkeypatch.setattr(cmp, "start_ray", _refuse_ray)
    status, out, err = cli(["compare", "--out", str(tmp_path / "c"), *args])
    assert status == 2
    assert err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "c").exists()


# ------------------------------------------------------------------ end to end on a local Ray


@pytest.fixture(scope="module")
def two_workers(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int]:
    """Compare as a user runs it: it starts its own local Ray of two CPUs, and shuts it down."""
    import ray

    assert not ray.is_initialized(), "a Ray is running (shared_ray's?): compare would not start its own"
    out = tmp_path_factory.mktemp("compare") / "out"
    status = main(["compare", "--plants", ",".join(PLANTS), "--workers", "2", "--out", str(out), *TINY])
    assert not ray.is_initialized()  # shut down again
    return out, status


@pytest.fixture(scope="module")
def shared_ray() -> Iterator[None]:
    """One local Ray of two CPUs for the module's later compares (one Ray start, not one each):
    compare uses a Ray it finds running, and leaves it running."""
    with local_ray(__name__):
        yield


def test_compare_runs_episodes_as_ray_tasks(two_workers) -> None:
    out, status = two_workers
    assert status == 0
    for name in ("table.md", "table.csv", "chart.png", "compare.json"):
        assert (out / name).is_file(), name
    report = json.loads((out / "compare.json").read_text())
    assert report["status"] == "complete" and report["ray"]["address"] == "local"
    episodes = report["episodes"]
    assert [(e["plant"], e["seg_mode"]) for e in episodes] == [(p, m) for p in PLANTS for m in cmp.SEG_MODES]
    for e in episodes:
        assert e["status"] == "complete", e
        assert e["pid"] != os.getpid()  # ran in a Ray worker, not here
        assert len(e["task_id"]) > 16 and e["node_id"]
        assert e["rss_peak_mb"] > 0 and e["wall_s"] > 0
        assert Path(e["run_dir"]) == out / e["plant"] / e["seg_mode"]
    assert len({e["task_id"] for e in episodes}) == 4
    assert len({e["pid"] for e in episodes}) == 4  # max_calls=1: a fresh worker process per episode


def test_table_rows_are_the_runs_metrics(two_workers) -> None:
    out, _ = two_workers
    table = {r["plant"]: r for r in csv.DictReader(io.StringIO((out / "table.csv").read_text())) if r["label"] == "all"}
    assert list(table) == list(PLANTS)
    md = (out / "table.md").read_text()
    for plant in PLANTS:
        m = {
            mode: json.loads((out / plant / mode / "metrics.json").read_text())["labels"]["all"]
            for mode in cmp.SEG_MODES
        }
        row = table[plant]
        for mode in cmp.SEG_MODES:
            assert int(row[f"pixels_{mode}"]) == m[mode]["pixels"]
            assert int(row[f"points_{mode}"]) == m[mode]["points"]
            assert float(row[f"precision_2mm_{mode}"]) == m[mode]["precision"]["2"]
            assert float(row[f"chamfer_mm_{mode}"]) == m[mode]["chamfer_mm"]
        pct = 100 * (m["repopa"]["pixels"] / m["texture"]["pixels"] - 1)
        assert float(row["pixels_pct"]) == pytest.approx(pct)
        px = f"{m['texture']['pixels'] / 1e6:.3f} | {m['repopa']['pixels'] / 1e6:.3f} | {pct:.2f}"
        assert f"| {cmp.plant_title(plant)} | {px} |" in md
    # RepOpa labels the cut-away parts of the grass's alpha cards: more pixels, lower precision
    grass = table["basket_grass"]
    assert float(grass["pixels_pct"]) > 20
    assert float(grass["precision_2mm_repopa"]) < float(grass["precision_2mm_texture"])


def test_one_worker_gives_identical_results(two_workers, shared_ray, tmp_path: Path) -> None:
    import ray

    out2, _ = two_workers
    out1 = tmp_path / "one"
    assert main(["compare", "--plants", "basket_grass", "--workers", "1", "--out", str(out1), *TINY]) == 0
    report = json.loads((out1 / "compare.json").read_text())
    assert report["ray"]["address"] == "existing" and not report["ray"]["owned"]
    assert ray.is_initialized()  # a Ray compare found is left running
    episodes = report["episodes"]
    assert [e["status"] for e in episodes] == ["complete"] * 2
    assert len({e["pid"] for e in episodes} | {os.getpid()}) == 3  # each in a fresh Ray worker
    # one at a time: the second was submitted when the first had finished
    first, second = sorted(episodes, key=lambda e: e["submitted_s"])
    assert second["submitted_s"] >= first["finished_s"]
    for mode in cmp.SEG_MODES:
        a = json.loads((out1 / "basket_grass" / mode / "metrics.json").read_text())
        b = json.loads((out2 / "basket_grass" / mode / "metrics.json").read_text())
        assert a == b
    rows1 = list(csv.DictReader(io.StringIO((out1 / "table.csv").read_text())))
    rows2 = [r for r in csv.DictReader(io.StringIO((out2 / "table.csv").read_text())) if r["plant"] == "basket_grass"]
    assert rows1 == rows2


def test_existing_out_is_refused_and_resume_skips_complete_runs(two_workers, no_ray, cli) -> None:
    out, _ = two_workers
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}
    status, _, err = cli(["compare", "--plants", ",".join(PLANTS), "--out", str(out), *TINY])
    assert status == 2 and "already exists; pass --overwrite" in err
    status, _, err = cli(["compare", "--plants", ",".join(PLANTS), "--out", str(out), "--resume", *TINY[:-2]])
    assert status == 2 and "metrics.truth_samples" in err  # made with other settings: never mixed
    after = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}
    assert after == before
    table = (out / "table.csv").read_text()
    # every run complete: nothing runs (no_ray), the table is rebuilt from the run directories
    status, stdout, _ = cli(["compare", "--plants", ",".join(PLANTS), "--out", str(out), "--resume", *TINY])
    assert status == 0 and "were complete already" in stdout
    assert (out / "table.csv").read_text() == table
    assert all(e["status"] == "skipped" for e in json.loads((out / "compare.json").read_text())["episodes"])
    for p, t in before.items():
        if p.parent != out:  # the run directories are untouched
            assert p.stat().st_mtime_ns == t, p


# ------------------------------------------------------------------ the paper's Table 3


def test_table_3_runs_the_mesh_then_each_point_size(shared_ray, tmp_path: Path) -> None:
    """Coltsfoot as its mesh and as points of two sizes: the table's figures are the runs'
    metrics, and bigger spheres label more pixels and stand further off the surface."""
    out = tmp_path / "t3"
    status = main(
        [
            "compare",
            "--plants",
            "coltsfoot",
            "--as-points",
            "8000",
            "--point-sizes",
            "0.002,0.008",
            "--workers",
            "2",
            "--out",
            str(out),
            *TINY,
        ]
    )
    assert status == 0
    assert sorted(p.name for p in (out / "coltsfoot").iterdir()) == ["mesh", "points-0.002", "points-0.008"]
    rows = list(csv.DictReader(io.StringIO((out / "table.csv").read_text())))
    assert [r["variant"] for r in rows] == ["mesh", "0.002", "0.008"]
    for r in rows:
        run = out / "coltsfoot" / (r["variant"] if r["variant"] == "mesh" else f"points-{r['variant']}")
        doc = json.loads((run / "metrics.json").read_text())["labels"]["all"]
        assert int(r["pixels"]) == doc["pixels"] and int(r["points"]) == doc["points"]
        assert float(r["thickness_mm"]) == doc["thickness_mm"]
        cfg = json.loads((run / "run.json").read_text())["config"]["points"]
        assert cfg == (
            {"count": None, "size": None} if r["variant"] == "mesh" else {"count": 8000, "size": float(r["variant"])}
        )
    small, big = rows[1], rows[2]
    assert int(big["pixels"]) > int(small["pixels"])
    assert float(big["thickness_mm"]) > float(small["thickness_mm"]) > 0
    md = (out / "table.md").read_text()
    assert "| Coltsfoot | mesh |" in md and "| Coltsfoot | 2 mm (0.2) |" in md and "Thickness (mm)" in md
    assert (out / "chart.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

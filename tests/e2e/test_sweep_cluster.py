"""``agrisim sweep --ray-address`` on a real cluster of several Ray nodes, all on loopback:
Ray's own multi-node harness (``ray.cluster_utils.Cluster``, what Ray's suite uses), a head that
runs nothing and two worker nodes of one core each. One worker node is removed (its raylet and
its workers killed) while the sweep runs on it; the sweep must still end with every run complete
and no view taken twice.

Ray puts a node on the address it would reach the network by, not on loopback; on Linux,
``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0`` keeps every node on 127.0.0.1, as Ray does on macOS, so
nothing here is addressed beyond this machine.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import isolated_env

SPEC = """\
physics.backend = "kinematic"
routine.setpoints = "2x4"  # 16 views: long enough to be caught mid-run
camera.resolution = "320x180"
metrics.truth_samples = 20000
[renderer.raycast]
shadow_samples = 0
[axes]
pcg_seed = [1, 2, 3]
"""
VIEWS = 16
LOOPBACK = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0", "RAY_USAGE_STATS_ENABLED": "0"}


@pytest.fixture
def cluster(monkeypatch: pytest.MonkeyPatch) -> Iterator[object]:
    """A head with no CPUs (it schedules, runs nothing) and two worker nodes of one CPU each."""
    for key, value in LOOPBACK.items():
        monkeypatch.setenv(key, value)  # for the nodes' processes, started from here
    import ray
    from ray._private import ray_constants
    from ray.cluster_utils import Cluster

    if ray.is_initialized():  # (another module's local Ray: this test needs its own cluster)
        ray.shutdown()
    monkeypatch.setattr(ray_constants, "ENABLE_RAY_CLUSTER", False)  # this process read it at import
    # the head's GCS checks each node every second and declares it dead after three missed
    # checks of 2 s each (Ray's defaults: every 3 s, five of 10 s: 15 s or more of waiting on the
    # lost node), as Ray's own failure tests shorten them; a node under load still answers a
    # check well within 2 s
    health = {"health_check_period_ms": 1000, "health_check_failure_threshold": 3, "health_check_timeout_ms": 2000}
    made = Cluster(
        initialize_head=True, head_node_args={"num_cpus": 0, "include_dashboard": False, "_system_config": health}
    )
    nodes = [made.add_node(num_cpus=1) for _ in range(2)]
    made.wait_for_nodes()
    made.workers = nodes  # type: ignore[attr-defined]
    yield made
    made.shutdown()


def _under_way(out: Path) -> dict[str, int]:
    """Views saved by each run that has begun and not finished (``run.json`` says running)."""
    under_way = {}
    for run in out.iterdir():
        if (run / "run.json").is_file():
            try:
                doc = json.loads((run / "run.json").read_text())
            except ValueError:  # (being rewritten this instant)
                continue
            views = len(doc.get("frames_complete") or [])
            if doc.get("status") == "running" and views < VIEWS:
                under_way[run.name] = views
    return under_way


def test_a_sweep_survives_a_node_lost_mid_sweep(cluster, tmp_path: Path) -> None:  # noqa: ANN001
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    out = tmp_path / "sweep"
    address = cluster.address  # type: ignore[attr-defined]
    sweep = subprocess.Popen(
        [sys.executable, "-m", "agrisim", "sweep", str(spec), "--out", str(out), "--ray-address", address],
        env=isolated_env(**LOOPBACK),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    # wait until both nodes hold a run (the head runs nothing) and one of them has saved a view:
    # a run's views take a few seconds of its ~12, and on a slow machine one node's worker starts
    # seconds after the other's, so two runs mid-views at once is not certain to be seen; two
    # runs begun and not finished is, with two nodes and three runs. Then lose one node with
    # the run it holds
    deadline = time.monotonic() + 240
    under_way: dict[str, int] = {}
    while time.monotonic() < deadline and sweep.poll() is None:
        time.sleep(0.05)
        if out.is_dir():
            under_way = _under_way(out)
            if len(under_way) == 2 and max(under_way.values()) >= 1:
                break
    assert sweep.poll() is None, sweep.communicate()
    assert len(under_way) == 2, f"never saw both nodes hold a run: {under_way}"
    started = set(under_way)
    lost = cluster.workers[0]  # type: ignore[attr-defined]
    cluster.remove_node(lost, allow_graceful=False)  # its raylet and workers killed at once
    killed_at = time.time()
    stdout, stderr = sweep.communicate(timeout=420)
    assert sweep.returncode == 0, stderr

    manifest = json.loads((out / "sweep.json").read_text())
    runs = manifest["runs"]
    assert len(runs) == 3 and len({r["name"] for r in runs}) == 3
    for r in runs:
        run = json.loads((out / r["name"] / "run.json").read_text())
        frames = run["frames_complete"]
        assert run["status"] == "complete" and r["status"] == "complete", (r, run["status"])
        assert len(frames) == VIEWS and len(set(frames)) == VIEWS  # every view once, none twice
        for folder in ("rgb", "labels", "depth"):
            assert sorted(p.stem for p in (out / r["name"] / folder).glob("*.png")) == sorted(frames)
    assert not [p for p in out.rglob("*.tmp*")], "no temporary file left behind"
    # the run the lost node held was retried on the other: of the two runs under way at the
    # loss, one ended in an attempt that began after it, elsewhere
    retried = [r for r in runs if r["name"] in started and r["started"] > killed_at]
    assert len(retried) == 1 and retried[0]["node_id"] != lost.node_id, [
        (r["name"], r.get("action"), r.get("node_id"), r.get("started"), killed_at) for r in runs
    ]

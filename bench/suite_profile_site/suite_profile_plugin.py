"""The pytest side of ``bench/suite_profile.py`` (``-p suite_profile_plugin``, in every xdist
worker): names the running test and phase in ``$SUITE_PROFILE_TEST`` (children inherit it), and
records each phase's seconds, its CPU seconds and the Dr.Jit kernels it compiled."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator

import pytest
import sitecustomize as counters

_config: pytest.Config | None = None


def pytest_configure(config: pytest.Config) -> None:
    global _config
    _config = config


def _phase(item: pytest.Item, when: str) -> Iterator[None]:
    """Name the test and phase for this process and its children; drain Dr.Jit's kernels after."""
    os.environ[counters.TEST_ENV] = f"{item.nodeid}::{when}"
    start = time.process_time()
    try:
        return (yield)
    finally:
        counters.drain_kernels()
        counters.record("cpu", secs=time.process_time() - start)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_setup(item: pytest.Item) -> Iterator[None]:
    return (yield from _phase(item, "setup"))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Iterator[None]:
    return (yield from _phase(item, "call"))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_teardown(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    return (yield from _phase(item, "teardown"))


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if _config is None or _config.pluginmanager.has_plugin("dsession"):
        return  # xdist's controller: the worker that ran the test recorded it
    worker = getattr(_config, "workerinput", {}).get("workerid", "main")
    counters.record(
        "phase", node=report.nodeid, when=report.when, secs=report.duration, outcome=report.outcome, worker=worker
    )

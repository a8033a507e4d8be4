"""The plant cache (``AGRISIM_PLANT_CACHE``): a species grown once from a seed and options is
read back, by this process or another, as the very plant growing gives (its scene file byte for
byte); another seed, other options or another species is another entry; a broken entry is grown
again; with the cache off nothing is kept."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import isolated_env

from agrisim.config import build_config
from agrisim.plant_choice import resolve_plant
from agrisim.plugins.sinks.dataset.glb import export_glb
from agrisim.registry import Registry, make_plugin_manager
from agrisim.scene import plant_cache
from agrisim.scene.plant_cache import PLANT_CACHE_ENV


def scene_file(plant, path: Path) -> bytes:  # noqa: ANN001
    export_glb(plant.mesh, path, plant.labels)
    return path.read_bytes()


@pytest.fixture
def counted(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> list[tuple[str, int]]:
    """The cache in ``tmp_path/cache``; the species grown, in order, listed."""
    monkeypatch.setenv(PLANT_CACHE_ENV, str(tmp_path / "cache"))
    grows: list[tuple[str, int]] = []
    real = plant_cache.grown

    def grown(species, options, seed, grow):  # noqa: ANN001, ANN202
        return real(species, options, seed, lambda s: grows.append((species, s)) or grow(s))

    monkeypatch.setattr("agrisim.plant_choice.grown", grown)
    return grows


def plant(species: str, **settings: object):  # noqa: ANN201
    return resolve_plant(Registry(make_plugin_manager()), build_config({"plant": species, **settings}))


def test_a_kept_plant_is_the_grown_plant(counted, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    first = plant("coltsfoot", seed=3)
    again = plant("coltsfoot", seed=3)
    assert counted == [("coltsfoot", 3)]  # grown once, then read back
    assert len(list((tmp_path / "cache").glob("coltsfoot-3-*.pickle"))) == 1
    monkeypatch.delenv(PLANT_CACHE_ENV)
    fresh = plant("coltsfoot", seed=3)
    truth = scene_file(fresh, tmp_path / "fresh.glb")
    assert scene_file(first, tmp_path / "first.glb") == truth
    assert scene_file(again, tmp_path / "again.glb") == truth
    assert (again.name, again.seed, again.organs, again.notes) == (fresh.name, fresh.seed, fresh.organs, fresh.notes)
    again.mesh.vertices[:] = 0.0  # a copy of its own: the next reader gets the kept plant
    monkeypatch.setenv(PLANT_CACHE_ENV, str(tmp_path / "cache"))
    assert scene_file(plant("coltsfoot", seed=3), tmp_path / "third.glb") == truth


def test_another_seed_options_or_species_is_another_entry(counted) -> None:
    plant("coltsfoot", seed=3)
    plant("coltsfoot", seed=4)
    plant("coltsfoot", seed=3, plants={"coltsfoot": {"density": 0.5}})
    plant("amaryllis", seed=3)
    plant("coltsfoot", seed=3, plants={"coltsfoot": {"density": 0.5}})
    assert counted == [("coltsfoot", 3), ("coltsfoot", 4), ("coltsfoot", 3), ("amaryllis", 3)]


def test_a_broken_entry_is_grown_again(counted, tmp_path: Path) -> None:
    plant("coltsfoot", seed=3)
    (entry,) = (tmp_path / "cache").glob("*.pickle")
    entry.write_bytes(entry.read_bytes()[:100])
    plant("coltsfoot", seed=3)
    assert counted == [("coltsfoot", 3)] * 2
    plant("coltsfoot", seed=3)
    assert len(counted) == 2  # rewritten whole by the second growing


def test_another_process_reads_what_this_one_kept(counted, tmp_path: Path) -> None:
    truth = scene_file(plant("indian_cress", seed=5), tmp_path / "here.glb")
    code = (
        "from agrisim.scene import plant_cache\n"
        "def refuse(seed): raise SystemExit('grown again')\n"
        "from agrisim.config import build_config\n"
        "from agrisim.plugins.sinks.dataset.glb import export_glb\n"
        "from agrisim.registry import Registry, make_plugin_manager\n"
        "from agrisim.plant_choice import resolve_plant\n"
        "import agrisim.plant_choice as pc\n"
        "real = pc.grown\n"
        "pc.grown = lambda species, options, seed, grow: real(species, options, seed, refuse)\n"
        "p = resolve_plant(Registry(make_plugin_manager()), build_config({'plant': 'indian_cress', 'seed': 5}))\n"
        f"export_glb(p.mesh, {str(tmp_path / 'there.glb')!r}, p.labels)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], env=isolated_env(), capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert (tmp_path / "there.glb").read_bytes() == truth


def test_off_keeps_nothing(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.delenv(PLANT_CACHE_ENV, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert plant_cache.plant_cache_dir() is None
    plant("coltsfoot", seed=3)
    assert not list(tmp_path.rglob("*.pickle"))

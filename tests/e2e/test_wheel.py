"""agrisim as a library's users get it: the sdist and the wheel built from it (``python -m
build``, the way ``make wheel`` does, from the tracked files only, as a clean clone has them),
the wheel holding every module of core/ and plugins/, then installed into a fresh virtual
environment beside the lock's dependencies, where ``agrisim plants``, ``agrisim plugins`` and
``agrisim doctor`` work from the installed package, not from this checkout."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _tracked_copy(dest: Path) -> Path:
    """The tracked files (and those about to be, not ignored) copied to ``dest``."""
    files = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"],
        cwd=REPO,
        capture_output=True,
        check=True,
    ).stdout.split(b"\0")
    for name in filter(None, files):
        source = REPO / name.decode()
        if not source.exists() and not source.is_symlink():
            continue  # deleted in the work tree, not yet in the index
        target = dest / name.decode()
        target.parent.mkdir(parents=True, exist_ok=True)
        if source.is_symlink():
            target.symlink_to(os.readlink(source))
        else:
            shutil.copy2(source, target)
    return dest


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if shutil.which("git") is None:
        pytest.skip("git is needed to list the tracked files")
    tree = _tracked_copy(tmp_path_factory.mktemp("tree"))
    dist = tmp_path_factory.mktemp("dist")
    built = subprocess.run(
        [sys.executable, "-m", "build", "--no-isolation", "--outdir", str(dist), str(tree)],
        capture_output=True,
        text=True,
    )
    assert built.returncode == 0, built.stdout[-3000:] + built.stderr[-3000:]
    (wheel,) = dist.glob("agrisim-*.whl")
    assert len(list(dist.glob("agrisim-*.tar.gz"))) == 1
    return wheel


def test_the_wheel_holds_every_module(wheel: Path) -> None:
    names = set(zipfile.ZipFile(wheel).namelist())
    expected = {f"agrisim/{p.relative_to(REPO / 'core').as_posix()}" for p in (REPO / "core").rglob("*.py")}
    expected |= {
        f"agrisim/plugins/{p.relative_to(REPO / 'plugins').as_posix()}" for p in (REPO / "plugins").rglob("*.py")
    }
    expected.add("agrisim/plugins/render/arm_meshes_ur10.npz")  # package data: the cell's arm, decimated once
    missing = sorted(expected - names)
    assert not missing, f"the wheel lacks {missing[:10]}"
    entry_points = (
        zipfile.ZipFile(wheel).read(next(n for n in names if n.endswith(".dist-info/entry_points.txt"))).decode()
    )
    assert "[agrisim]" in entry_points and "agrisim = agrisim.app.cli:main" in entry_points


def test_the_wheel_installs_and_runs(wheel: Path, tmp_path: Path) -> None:
    uv = shutil.which("uv") or str(Path(sys.executable).with_name("uv"))
    venv = tmp_path / "venv"
    if Path(uv).exists():
        subprocess.run([uv, "venv", "-q", "--python", sys.executable, str(venv)], check=True)
        install = [uv, "pip", "install", "-q", "--python", str(venv / "bin" / "python")]
    else:  # setup.sh's fallback: pip
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        install = [str(venv / "bin" / "python"), "-m", "pip", "install", "-q"]
    subprocess.run([*install, "--require-hashes", "-r", str(REPO / "requirements.lock")], check=True)
    subprocess.run([*install, "--no-deps", str(wheel)], check=True)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    where = subprocess.run(
        [str(venv / "bin" / "python"), "-c", "import agrisim, agrisim.plugins; print(agrisim.__file__)"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    assert Path(where).is_relative_to(venv), f"agrisim came from {where}, not the installed wheel"

    def agrisim(*args: str) -> str:
        done = subprocess.run(
            [str(venv / "bin" / "agrisim"), *args], cwd=tmp_path, env=env, capture_output=True, text=True
        )
        assert done.returncode == 0, f"agrisim {' '.join(args)}: {done.stderr[-2000:]}"
        return done.stdout

    assert agrisim("--version").strip() == f"agrisim {wheel.name.split('-')[1]}"
    plants = agrisim("plants")
    assert "indian_cress" in plants and "hydrangea" in plants
    plugins = agrisim("plugins")
    for backend in ("raycast", "mitsuba", "pybullet", "ompl", "pointcloud", "coco", "rosbag", "nerfstudio"):
        assert backend in plugins
    doctor = agrisim("doctor", "--no-timing")
    assert "default run (agrisim run): can run here" in doctor

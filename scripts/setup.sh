#!/usr/bin/env bash
# Sets agrisim up from a clean clone: the one system library Open3D needs, a virtual
# environment in .venv, and exactly the dependency versions in requirements.lock (hash-checked),
# then agrisim itself in editable mode. Safe to run again: a venv that already matches the lock
# is left as it is.
#
# The lock is installed with uv (pinned below) because it is about 2.7x faster than pip on a cold
# cache (bench figures in the README); if uv cannot be installed, pip installs the same lock.
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3}
VENV=${VENV:-.venv}
LOCK=requirements.lock
UV_VERSION=0.13.9

have_libusb() { ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; }

if ! have_libusb; then
  # Open3D's wheel links against libusb-1.0 but does not ship it.
  if [ "$(id -u)" -eq 0 ]; then SUDO=""; else SUDO="sudo"; fi
  echo "agrisim setup: installing libusb-1.0-0 (needed by Open3D)"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libusb-1.0-0 >/dev/null
fi

# The raycast and mitsuba renderers on the CPU (Dr.Jit's LLVM backend) load a shared libLLVM at run
# time: 15 or newer, but LLVM 15's x86 backend aborted on an fminimum intrinsic here, so 16+.
have_libllvm() { ldconfig -p 2>/dev/null | grep -Eq 'libLLVM(-(1[6-9]|[2-9][0-9])[.0-9]*\.so|\.so\.(1[6-9]|[2-9][0-9]))'; }

if ! have_libllvm; then
  if command -v apt-get >/dev/null 2>&1; then
    if [ "$(id -u)" -eq 0 ]; then SUDO=""; else SUDO="sudo"; fi
    echo "agrisim setup: installing libllvm19 (the renderers' CPU backend, Dr.Jit's LLVM, needs libLLVM 16+)"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libllvm19 >/dev/null
  else
    echo "agrisim setup: no libLLVM 16+ found and no apt-get; the renderers' CPU backend (Dr.Jit's LLVM) needs one" >&2
    echo "  (install LLVM 16 or newer, or set DRJIT_LIBLLVM_PATH to its shared library)" >&2
  fi
fi

if ! "$PYTHON" -c 'import sys; sys.exit(sys.version_info < (3, 10))' 2>/dev/null; then
  echo "agrisim setup: $PYTHON is not Python 3.10 or newer; set PYTHON=python3.X" >&2
  exit 2
fi

if [ ! -x "$VENV/bin/python" ]; then
  "$PYTHON" -m venv "$VENV"
fi

# pip on some machines warns about configured package locations that do not exist; that noise
# is not ours to show.
quiet_pip() { "$VENV/bin/python" -m pip "$@" 2>&1 | { grep -v "is ignored" || true; }; }

# Skip the install when the venv was made from this very lock (and this agrisim checkout).
stamp="$VENV/.agrisim-lock.sha256"
want=$(cat "$LOCK" pyproject.toml | sha256sum | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  if [ ! -x "$VENV/bin/uv" ]; then
    quiet_pip install -q "uv==$UV_VERSION" || true
  fi
  if [ -x "$VENV/bin/uv" ]; then
    # Compiled now, as pip does by default and uv does not: where bytecode is never cached
    # (PYTHONDONTWRITEBYTECODE, common in containers) every run would compile its imports again,
    # half a second of a robot-only run.
    "$VENV/bin/uv" pip install -q --python "$VENV/bin/python" --compile-bytecode --require-hashes -r "$LOCK"
    "$VENV/bin/uv" pip install -q --python "$VENV/bin/python" --no-deps -e .
  else
    echo "agrisim setup: uv unavailable, installing $LOCK with pip"
    quiet_pip install -q --require-hashes -r "$LOCK"
    quiet_pip install -q --no-deps -e .
  fi
  echo "$want" >"$stamp"
fi

# agrisim's own modules too (an editable install leaves them where they are); only what changed
# since the last time is compiled again.
"$VENV/bin/python" -m compileall -q core plugins >/dev/null

# pybullet announces its build time on import: keep the check quiet unless it fails.
if ! out=$("$VENV/bin/python" -c "import agrisim, open3d, pinocchio, pybullet, ompl, ruckig, rerun" 2>&1); then
  echo "$out" >&2
  echo "agrisim setup: the installation is incomplete" >&2
  exit 1
fi

#!/usr/bin/env bash
# Sets agrisim up from a clean clone: the one system library Open3D needs, a virtual
# environment in .venv, and the package with its extras. Safe to run again.
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3}
VENV=${VENV:-.venv}

have_libusb() { ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; }

if ! have_libusb; then
  # Open3D's wheel links against libusb-1.0 but does not ship it.
  if [ "$(id -u)" -eq 0 ]; then SUDO=""; else SUDO="sudo"; fi
  echo "agrisim setup: installing libusb-1.0-0 (needed by Open3D)"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libusb-1.0-0 >/dev/null
fi

if [ ! -x "$VENV/bin/python" ]; then
  "$PYTHON" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --upgrade pip 2>&1 | grep -v "is ignored" || true
"$VENV/bin/python" -m pip install -q -e ".[dev,helios]" 2>&1 | grep -v "is ignored" || true
# pybullet announces its build time on import: keep the check quiet unless it fails.
if ! out=$("$VENV/bin/python" -c "import agrisim, open3d, pinocchio, pybullet, ompl, ruckig, rerun" 2>&1); then
  echo "$out" >&2
  echo "agrisim setup: the installation is incomplete" >&2
  exit 1
fi

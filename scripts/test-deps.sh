#!/usr/bin/env bash
# What the test suite needs beyond the Python lock: a real headless browser for the web viewer
# tests (tests/e2e/test_web_view.py), Debian's chromium-headless-shell, and Debian's ROS 1 for the
# live ROS tests (scripts/ros-deps.sh). Installed only for `make test`; `agrisim view` itself
# needs no browser on the machine that serves.
set -euo pipefail

bash "$(dirname "$0")/ros-deps.sh"

if command -v chromium-headless-shell >/dev/null 2>&1 || command -v chromium >/dev/null 2>&1; then
  exit 0
fi
if command -v apt-get >/dev/null 2>&1; then
  if [ "$(id -u)" -eq 0 ]; then SUDO=""; else SUDO="sudo"; fi
  echo "agrisim test set-up: installing chromium-headless-shell (the web viewer tests' browser)"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium-headless-shell >/dev/null
else
  echo "agrisim test set-up: no apt-get; install Chromium for the web viewer tests (they are skipped without it)" >&2
fi

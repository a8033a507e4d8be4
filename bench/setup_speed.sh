#!/usr/bin/env bash
# Cold-cache install of requirements.lock into a fresh venv: pip against uv (what
# scripts/setup.sh uses, compiling bytecode as pip does), both hash-checked, both followed by
# agrisim's editable install.
# Prints the CPU model and both wall times. Needs network access to PyPI; takes a few minutes.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
grep -m1 "model name" /proc/cpuinfo

start=$(date +%s.%N)
"$PYTHON" -m venv "$tmp/pip"
"$tmp/pip/bin/pip" install -q --no-cache-dir --require-hashes -r requirements.lock 2>&1 | { grep -v "is ignored" || true; }
"$tmp/pip/bin/pip" install -q --no-cache-dir --no-deps -e . 2>&1 | { grep -v "is ignored" || true; }
pip_s=$(echo "$(date +%s.%N) - $start" | bc)

start=$(date +%s.%N)
"$PYTHON" -m venv "$tmp/uv"
"$tmp/uv/bin/pip" install -q --no-cache-dir "uv==$(sed -n 's/^UV_VERSION=//p' scripts/setup.sh)" 2>&1 | { grep -v "is ignored" || true; }
"$tmp/uv/bin/uv" pip install -q --no-cache --python "$tmp/uv/bin/python" --compile-bytecode --require-hashes -r requirements.lock
"$tmp/uv/bin/uv" pip install -q --no-cache --python "$tmp/uv/bin/python" --no-deps -e .
uv_s=$(echo "$(date +%s.%N) - $start" | bc)

printf 'pip: %.1f s\nuv (including installing uv): %.1f s\npip / uv: %.2fx\n' "$pip_s" "$uv_s" "$(echo "$pip_s / $uv_s" | bc -l)"

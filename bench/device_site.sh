#!/bin/bash
# One file that carries what agrisim's GPU benches need to a GPU machine with no package index
# (Python 3.12): an installed site-packages, slimmed and compressed with xz, for
# bench/device_install.sh to unpack there.
#   bash bench/device_site.sh OUT.tar.xz [--ray] [--no-mitsuba] [NAME==VERSION ...]
# Always: the light dependencies of agrisim's core (pydantic, pygltflib, isal, pluggy, rich, as
# locked); Mitsuba and Dr.Jit (slimmed by shared/tools/device-wheels.sh: three variants) unless
# --no-mitsuba. pyoidn, when named, loses its SYCL, HIP and Level Zero back ends (CPU and CUDA
# stay): 47 MB packed, most of it the network weights.
# --ray adds Ray as locked, slimmed: no Java jars (32 MB), no dashboard web build, none of its
# libraries (RLlib, Serve, Data, Train, Tune, LLM), its three native binaries stripped of their
# symbol tables (120 MB -> 84 MB); Ray's core runs as before (tasks, GPUs, retries).
# Sizes measured: with --ray 48.7 MB (288 MB unpacked); the device's carry holds 64 MiB.
# Extra NAME==VERSION wheels (e.g. gsplat==1.5.3 wadler-lindig==0.1.7) go in as they are.
set -euo pipefail
out=$(realpath -m "$1")
shift
ray=0
mitsuba=1
extra=()
for arg in "$@"; do
  case "$arg" in
    --ray) ray=1 ;;
    --no-mitsuba) mitsuba=0 ;;
    *) extra+=("$arg") ;;
  esac
done
repo=$(cd "$(dirname "$0")/.." && pwd)
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
platforms=(--platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64
  --platform manylinux2014_x86_64 --platform manylinux1_x86_64)
locked() { grep -E "^($1)==" "$repo/requirements.lock" | sed 's/ .*//' | sort -V | tail -1; }
pins=()
for name in pydantic pydantic-core annotated-types typing-inspection typing-extensions pygltflib \
  dataclasses-json marshmallow typing-inspect mypy-extensions isal pluggy rich markdown-it-py mdurl pygments; do
  pins+=("$(locked "$name")")
done
if [ $ray = 1 ]; then
  for name in ray click msgpack jsonschema jsonschema-specifications referencing rpds-py attrs protobuf pyyaml \
    filelock packaging requests urllib3 idna certifi charset-normalizer; do
    pins+=("$(locked "$name")")
  done
fi
if [ $mitsuba = 1 ]; then bash "$repo/../shared/tools/device-wheels.sh" "$tmp/wheels" >/dev/null; fi
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp "${platforms[@]}" \
  -d "$tmp/wheels" "${pins[@]}" "${extra[@]}"
# pip installs for the other Python (3.12) by its tags; it keeps the binaries' exec bits
python3 -m pip install -q --no-deps --no-compile --only-binary=:all: --python-version 3.12 --implementation cp \
  "${platforms[@]}" --target "$tmp/site" "$tmp"/wheels/*.whl
site=$tmp/site
rm -rf "$site"/mitsuba/include "$site"/bin
if [ -d "$site"/pyoidn ]; then
  rm -rf "$site"/pyoidn/oidn/bin "$site"/pyoidn/oidn/include "$site"/pyoidn/oidn/lib/cmake
  rm -f "$site"/pyoidn/oidn/lib/{libur_*,libsycl*,libumf*,libtbbbind*,libOpenImageDenoise_device_hip*,libOpenImageDenoise_device_sycl*}
fi
if [ $ray = 1 ]; then
  rm -rf "$site"/ray/jars "$site"/ray/dashboard/client/build "$site"/ray/{rllib,serve,data,train,tune,llm}
  strip --strip-unneeded "$site"/ray/_raylet.so "$site"/ray/core/src/ray/raylet/raylet "$site"/ray/core/src/ray/gcs/gcs_server
fi
tar -C "$site" -cf - . | xz -9e -T0 > "$out"
echo "$out: $(du -m "$out" | cut -f1) MB ($(du -sm "$site" | cut -f1) MB unpacked)"

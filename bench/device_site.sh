#!/bin/bash
# One file that carries what agrisim's GPU benches need to a GPU machine with no package index
# (Python 3.12): an installed site-packages, slimmed and compressed with xz, for
# bench/device_install.sh to unpack there.
#   bash bench/device_site.sh OUT.tar.xz [--ray] [--robot] [--no-mitsuba] [NAME==VERSION ...]
# Always: the light dependencies of agrisim's core (pydantic, pygltflib, isal, pluggy, rich, as
# locked); Mitsuba and Dr.Jit (slimmed by shared/tools/device-wheels.sh: three variants) unless
# --no-mitsuba. pyoidn, when named, loses its SYCL, HIP and Level Zero back ends (CPU and CUDA
# stay): 47 MB packed, most of it the network weights.
# --ray adds Ray as locked, slimmed: no Java jars (32 MB), no dashboard web build, none of its
# libraries (RLlib, Serve, Data, Train, Tune, LLM), its three native binaries stripped of their
# symbol tables (120 MB -> 84 MB); Ray's core runs as before (tasks, GPUs, retries).
# --robot adds what an episode's arms need (agrisim/PlantView-v0, bench/nextview_speed.py), as
# locked: Pinocchio (pin, libpinocchio), Coal, EigenPy and their cmeel libraries, OMPL, Ruckig,
# Gymnasium, trimesh and pycollada (the UR10's .dae visuals), prosail and colour-science (the
# procedural plants' leaf optics; colour without the 76 MB coverage report its wheel ships, nor
# its tests), example-robot-data with the UR10's description alone (131 MB wheel -> 9 MB
# unpacked); no headers, static or CMake files, docs, nor the Boost libraries no kept library
# needs (readelf NEEDED); the cmeel libraries stripped of their symbol tables. scipy, networkx and
# numba are the device's own. No Open3D nor pybullet: run with physics.backend=kinematic and
# renderer.raycast.arm_triangles=0 (renderer.mitsuba.arm_triangles=0 for mitsuba); an episode's
# end, which measures the reconstruction with Open3D, fails there. Python finds Pinocchio through
# cmeel's .pth file, which PYTHONPATH skips, so name its folder too:
#   export PYTHONPATH=/tmp/site:/tmp/site/cmeel.prefix/lib/python3.12/site-packages
# Sizes measured: with --ray 48.7 MB (288 MB unpacked); with --robot 49.7 MB (293 MB unpacked),
# which leaves about 17 MB of the device's carry (64 MiB) for the working tree.
# Extra NAME==VERSION wheels (e.g. gsplat==1.5.3 wadler-lindig==0.1.7) go in as they are.
set -euo pipefail
out=$(realpath -m "$1")
shift
ray=0
robot=0
mitsuba=1
extra=()
for arg in "$@"; do
  case "$arg" in
    --ray) ray=1 ;;
    --robot) robot=1 ;;
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
if [ $robot = 1 ]; then
  for name in pin libpinocchio coal libcoal eigenpy cmeel cmeel-boost cmeel-assimp cmeel-qhull cmeel-octomap \
    cmeel-urdfdom cmeel-console-bridge cmeel-tinyxml2 cmeel-zlib ompl ruckig gymnasium cloudpickle \
    farama-notifications trimesh pycollada prosail colour-science example-robot-data; do
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
if [ $robot = 1 ]; then
  prefix=$site/cmeel.prefix
  rm -rf "$site"/{include,lib64,share} "$prefix"/{bin,include,lib64/cmake,lib64/pkgconfig,lib/cmake,lib/pkgconfig}
  rm -rf "$prefix"/lib/{console_bridge,urdfdom} "$prefix"/share/{doc,man}
  find "$site" -name '*.a' -delete
  rm -rf "$site"/colour/{htmlcov,examples}
  find "$site"/colour -type d -name tests -prune -exec rm -rf {} +
  robots=$prefix/share/example-robot-data/robots
  find "$robots" -mindepth 1 -maxdepth 1 ! -name ur_description -exec rm -rf {} +
  rm -rf "$robots"/ur_description/{launch,srdf,meshes/ur3,meshes/ur5}
  find "$robots"/ur_description/urdf -type f ! -name ur10_robot.urdf -delete
  # the cmeel libraries that the Python extensions need, by name (NEEDED), and theirs in turn;
  # pip copies each library once per link name (libX.so, .so.N, .so.N.M): only the needed names stay
  python3 - "$site" <<'PY'
import pathlib
import subprocess
import sys

site = pathlib.Path(sys.argv[1])
libdirs = [site / "cmeel.prefix" / "lib", site / "cmeel.prefix" / "lib64"]
libs = {p.name: p for d in libdirs for p in d.iterdir() if p.is_file() and ".so" in p.name}


def needed(path: pathlib.Path) -> list[str]:
    out = subprocess.run(["readelf", "-d", str(path)], capture_output=True, text=True, check=True).stdout
    return [line.split("[")[1].rstrip("]") for line in out.splitlines() if "(NEEDED)" in line]


todo = [p for p in site.rglob("*.so") if p.parent not in libdirs]
keep: set[str] = set()
while todo:
    for name in needed(todo.pop()):
        if name in libs and name not in keep:
            keep.add(name)
            todo.append(libs[name])
for name, path in libs.items():
    if name not in keep:
        path.unlink()
print(f"cmeel libraries kept: {' '.join(sorted(keep))}", file=sys.stderr)
PY
  find "$prefix" -name '*.so*' -type f -exec strip --strip-unneeded {} +
fi
tar -C "$site" -cf - . | xz -9e -T0 > "$out"
echo "$out: $(du -m "$out" | cut -f1) MB ($(du -sm "$site" | cut -f1) MB unpacked)"

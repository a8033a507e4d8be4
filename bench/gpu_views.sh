#!/bin/bash
# The mitsuba renderer's rate on a GPU machine, in one call: a minimal install (bench/device_install.sh),
# where a 1080p view's time goes at the defaults (bench/mitsuba_frame_cost.py), then `agrisim render`
# at the defaults of a saved run at 1080p and at 960x540 (the same run, its camera halved), PNGs
# written, timed whole and per view (the first view compiles: the rate counts the views after it).
#   bash bench/gpu_views.sh RUN [WHEELS] [SPP...]
# SPP: samples per pixel of the accounting runs (default: 8, the renderer's default).
# RUN: a saved run (scene/lab.glb, cameras.json, run.json, link_poses/; its images are not needed).
set -uo pipefail  # (no -e: one failing step should not hide the others' figures)
run=$1
wheels=${2:-.whl}
shift $(($# >= 2 ? 2 : 1))
bash bench/device_install.sh "$wheels" /tmp/site || exit 1
export PYTHONPATH=/tmp/site
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
for spp in "${@:-8}"; do
  python3 bench/mitsuba_frame_cost.py "$run" --variant cuda --spp "$spp" --frames 10 --denoise auto
done

# The carried run left its images behind; agrisim render checks that the run's frames are complete
# (rgb, labels, depth), not what they hold: empty stand-ins in a copy.
full=/tmp/run-1920x1080
rm -rf "$full" && cp -r "$run" "$full"
python3 bench/stand_in_images.py "$full"
half=/tmp/run-960x540
rm -rf "$half" && cp -r "$full" "$half"
python3 - "$half/cameras.json" <<'PY'
import json, sys
doc = json.load(open(sys.argv[1]))
c = doc["intrinsics"]
K = c["K"]
# pixel centres are integers: a pixel's centre maps to (x + 0.5) / 2 - 0.5
K[0][0] /= 2; K[1][1] /= 2; K[0][2] = (K[0][2] + 0.5) / 2 - 0.5; K[1][2] = (K[1][2] + 0.5) / 2 - 0.5
c["width"] //= 2; c["height"] //= 2
json.dump(doc, open(sys.argv[1], "w"))
PY
for r in "$full" "$half"; do
  out=/tmp/rendered-$(basename "$r")
  rm -rf "$out"
  t0=$(date +%s.%N)
  python3 -m agrisim render "$r" --renderer mitsuba --out "$out" > /tmp/render.log 2>&1 || { tail -20 /tmp/render.log; continue; }
  echo "agrisim render $(basename "$r"): $(python3 -c "print(f'{$(date +%s.%N) - $t0:.1f}')") s, the whole command"
  python3 - "$out" "$t0" <<'PY'
import json, os, sys
from pathlib import Path
out = Path(sys.argv[1])
pngs = sorted((out / "rgb").glob("*.png"), key=os.path.getmtime)
t = [os.path.getmtime(p) for p in pngs]
start = float(sys.argv[2])
doc = json.load(open(out / "render.json"))
rate = (len(t) - 1) / (t[-1] - t[0])
print(f"agrisim render {out.name}: {len(pngs)} PNGs, status {doc['status']}; first PNG {t[0] - start:.1f} s "
      f"after the start; then {rate:.2f} views/s ({1e3 / rate:.0f} ms a view); options {doc['options']}")
PY
done

#!/bin/bash
# `agrisim render` on 1, 2 and 4 GPUs of one host, in one call on a multi-GPU machine: the
# views/s at the mitsuba defaults, and the scaling efficiency against one GPU. Prints figures.
#   bash bench/gpu_scaling.sh RUN SITE [GPUS...]      (default GPUS: 1 2 4)
# RUN: a saved run (scene/, cameras.json, run.json, link_poses/; images not needed), e.g. a
# 100-view 1080p run with arms. SITE: bench/device_site.sh's packed site with --ray.
# For each GPU count G (CUDA_VISIBLE_DEVICES=0..G-1, which Ray counts its GPUs by):
#   four runs: `agrisim render R0 R1 R2 R3`, a Ray task per run, one per GPU;
#   one run: `agrisim render R0`, its frames dealt out over the G GPUs (G = 1: no Ray at all).
# Rates: views over the whole command (start-up, Ray, Mitsuba's compiling, PNGs written), and
# the steady rate between the first and the last PNG written.
set -uo pipefail  # (no -e: one failing step should not hide the others' figures)
run=$1
site=$2
shift 2
counts=("${@:-1 2 4}")
[ $# -eq 0 ] && counts=(1 2 4)
bash bench/device_install.sh "$site" /tmp/site || exit 1
export PYTHONPATH=/tmp/site RAY_USAGE_STATS_ENABLED=0
nvidia-smi --query-gpu=index,name,driver_version --format=csv,noheader
nproc
work=/tmp/scaling && rm -rf "$work" && mkdir -p "$work"
for i in 0 1 2 3; do
  cp -r "$run" "$work/r$i"
  # agrisim render checks that the run's frames are complete (rgb, labels, depth), not what
  # they hold: empty stand-ins for the images the carry left behind
  python3 bench/stand_in_images.py "$work/r$i"
done
log=$work/figures.jsonl
for g in "${counts[@]}"; do
  devices=$(seq -s, 0 $((g - 1)))
  for what in four one; do
    rm -rf "$work"/r?-mitsuba
    if [ $what = four ]; then sources=("$work"/r0 "$work"/r1 "$work"/r2 "$work"/r3); else sources=("$work"/r0); fi
    t0=$(date +%s.%N)
    CUDA_VISIBLE_DEVICES=$devices python3 -m agrisim render "${sources[@]}" > "$work/log-$what-$g" 2>&1 \
      || { tail -20 "$work/log-$what-$g"; continue; }
    t1=$(date +%s.%N)
    python3 - "$g" "$what" "$t0" "$t1" "$log" "${sources[@]}" <<'PY'
import json, os, sys
from pathlib import Path
g, what, t0, t1, log, *sources = sys.argv[1:]
t0, t1 = float(t0), float(t1)
pngs = [p for s in sources for p in Path(f"{s}-mitsuba/rgb").glob("*.png")]
t = sorted(os.path.getmtime(p) for p in pngs)
docs = [json.loads(Path(f"{s}-mitsuba/render.json").read_text()) for s in sources]
row = {
    "gpus": int(g), "runs": what, "views": len(pngs), "status": sorted({d["status"] for d in docs}),
    "command_s": round(t1 - t0, 2), "first_png_s": round(t[0] - t0, 2),
    "views_per_s": round(len(pngs) / (t1 - t0), 3), "steady_views_per_s": round((len(t) - 1) / (t[-1] - t[0]), 3),
}
print(json.dumps(row), flush=True)
with open(log, "a") as f:
    f.write(json.dumps(row) + "\n")
PY
  done
done
python3 - "$log" <<'PY'
import json, sys
rows = [json.loads(line) for line in open(sys.argv[1])]
print("| GPUs | runs | views | whole command, s | views/s | efficiency | steady views/s | efficiency |")
print("|---|---|---|---|---|---|---|---|")
for r in rows:
    base = next((b for b in rows if b["gpus"] == 1 and b["runs"] == r["runs"]), None)
    eff = lambda key: f"{r[key] / (r['gpus'] * base[key]):.0%}" if base else "-"
    n = 4 if r["runs"] == "four" else 1
    print(f"| {r['gpus']} | {n} x {r['views'] // n} | {r['views']} | {r['command_s']:.1f} "
          f"| {r['views_per_s']:.2f} | {eff('views_per_s')} | {r['steady_views_per_s']:.2f} | {eff('steady_views_per_s')} |")
PY
[ -n "${OUT:-}" ] && cp "$log" "$OUT/" 2>/dev/null
true

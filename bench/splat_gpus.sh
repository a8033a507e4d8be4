#!/bin/bash
# The splat table's wall time on 1, 2 and 4 GPUs of one host (bench/splat_table.py train), on a
# GPU machine with no package index: a minimal install from SITE (bench/device_site.sh with
# gsplat==1.5.3 wadler-lindig==0.1.8), gsplat's CUDA code compiled once before any clock starts,
# then each species of CARRY (saved runs: scene/lab.glb, cameras.json, run.json, the empty image
# stand-ins of bench/stand_in_images.py) path-traced at Mitsuba's defaults and trained on true
# poses, a process per GPU.
#   bash bench/splat_gpus.sh CARRY SITE DEVICES [DEVICES ...]
# Each DEVICES (e.g. 0 or 1,2 or 0,1,2,3) is one table over those GPUs; several run at once, on
# separate GPUs, so that the 1- and 2-GPU tables fit one call.
set -uo pipefail
carry=$1
site=$2
shift 2
bash bench/device_install.sh "$site" /tmp/site || exit 1
export PYTHONPATH=/tmp/site TORCH_CUDA_ARCH_LIST=${TORCH_CUDA_ARCH_LIST:-9.0} PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=index,name,driver_version --format=csv,noheader
t0=$(date +%s)
python3 -c "from gsplat.cuda._backend import _C; print('gsplat', _C is not None)" 2>&1 | tail -1
echo "gsplat compiled in $(( $(date +%s) - t0 )) s"
species=$(ls "$carry")
for devices in "$@"; do
  python3 bench/splat_table.py train "$carry" --devices "$devices" --draw mitsuba --species $species \
    --out "/tmp/splat-gpus-${devices//,/}" > "/tmp/splat-gpus-${devices//,/}.log" 2>&1 &
done
wait
for devices in "$@"; do
  out=/tmp/splat-gpus-${devices//,/}
  echo "== GPUs $devices"; cat "$out.log"
  for f in "$out"/*.log; do grep -E "drawn by|PSNR|Error|error" "$f" | tail -3; done
  [ -n "${OUT:-}" ] && cp "$out"/gpus-*.json "$OUT/gpus-${devices//,/}.json" 2>/dev/null
done
python3 bench/splat_table.py table "/tmp/splat-gpus-${1//,/}"
true

#!/bin/bash
# Splats on the true poses against splats on COLMAP's, in one call on a GPU machine: a minimal
# install (bench/device_install.sh; WHEELS without Mitsuba, with gsplat 1.5.3 and its jaxtyping,
# wadler-lindig and ninja), then `agrisim recon RUN --recon splat` with recon.poses = truth and
# = colmap, each into a folder of its own, and their figures side by side.
#   bash bench/splat_poses.sh RUN [WHEELS] [-- more --set KEY=VALUE for both]
# RUN: a complete run made with --hide-robots, carried with its rgb/, labels/, depth/, scene/,
# run.json, cameras.json and colmap/poses.json (from `agrisim colmap RUN` on this machine's CPU;
# the GPU machine reads the poses and needs no pycolmap).
set -uo pipefail
run=$1
wheels=${2:-.whls}
shift $(($# >= 2 ? 2 : 1))
[ "${1:-}" = "--" ] && shift
bash bench/device_install.sh "$wheels" /tmp/site >/dev/null || exit 1
export PYTHONPATH=/tmp/site TORCH_CUDA_ARCH_LIST=${TORCH_CUDA_ARCH_LIST:-9.0}
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
work=/tmp/splat-poses && rm -rf "$work" && cp -r "$run" "$work"
for poses in truth colmap; do
  t0=$(date +%s)
  python3 -m agrisim recon "$work" --recon splat --set "recon.poses=$poses" "$@" --out "/tmp/splat-$poses" \
    > "/tmp/splat-$poses.log" 2>&1 || { tail -20 "/tmp/splat-$poses.log"; continue; }
  python3 - "/tmp/splat-$poses/metrics.json" "$(( $(date +%s) - t0 ))" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
s = m["splat"]
print(
    f"poses {m['poses']}: {m['frames']} views ({s['train_views']} trained, {s['test_views']} held out); "
    f"PSNR {s['psnr']:.2f} dB, SSIM {s['ssim']:.3f}, plant PSNR {s['psnr_plant']:.2f} dB, rendered depth "
    f"error median {s['depth_error_mm']['median']:.1f} mm; {s['gaussians']:,} Gaussians, "
    f"{s['train_seconds']:.0f} s training, {sys.argv[2]} s the command"
)
PY
done

"""The raycast renderer on the CPU (Dr.Jit's LLVM backend, Embree) and on the GPU (CUDA, OptiX)
on the same views of a saved run: labels, depth and RGB compared view by view. Prints figures;
asserts nothing. Needs a machine with an NVIDIA GPU; works from a minimal install (agrisim's
core, numpy, pydantic, pluggy, Mitsuba and Dr.Jit).

Mitsuba takes one variant per process, so each side renders in a process of its own.

    python bench/engine_devices.py RUN_DIR [--views 10] [--shadow-samples 0 1]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import cpu_model, gpu_name  # noqa: E402

WORKER = r"""
import json, sys, numpy as np
from pathlib import Path
from agrisim.config import RenderConfig
from agrisim.files import layout
from agrisim.files.rundir import camera_from_json
from agrisim.plugins.formats.scene_glb import read_scene
from agrisim.plugins.render.raycast import RaycastOptions
from agrisim.plugins.render.raycast.renderer import RaycastRenderer
run, variant, views, samples, out = Path(sys.argv[1]), sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
cameras = json.loads((run / "cameras.json").read_text())
camera = camera_from_json(cameras["intrinsics"])
scene = read_scene(run / "scene" / "lab.glb")
r = RaycastRenderer(scene, None, RenderConfig(hide_robots=False), RaycastOptions(variant=variant, shadow_samples=samples))
images = {}
for f in list(cameras["frames"])[:views]:
    poses = {k: {l: np.asarray(T) for l, T in v.items()} for k, v in json.loads(layout.link_poses(run, f).read_text()).items()}
    frame = r.render(camera, np.asarray(cameras["frames"][f]["world_T_camera"]), poses)
    images[f + "_rgb"], images[f + "_labels"], images[f + "_depth"] = frame.rgb, frame.labels, frame.depth
np.savez(out, **images)
"""


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(((a.astype(np.float64) - b) ** 2).mean())
    return 10 * np.log10(255.0**2 / mse) if mse > 0 else float("inf")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--views", type=int, default=10)
    parser.add_argument("--shadow-samples", type=int, nargs="+", default=[0, 1])
    args = parser.parse_args()
    print(f"CPU: {cpu_model()}; GPU: {gpu_name()}")
    with tempfile.TemporaryDirectory() as tmp:
        for samples in args.shadow_samples:
            out = {}
            for variant in ("llvm", "cuda"):
                out[variant] = Path(tmp) / f"{variant}.npz"
                subprocess.run(
                    [
                        sys.executable,
                        "-c",
                        WORKER,
                        str(args.run_dir),
                        variant,
                        str(args.views),
                        str(samples),
                        str(out[variant]),
                    ],
                    check=True,
                )
            cpu, gpu = np.load(out["llvm"]), np.load(out["cuda"])
            frames = sorted({k.rsplit("_", 1)[0] for k in cpu.files})
            labels = [float((cpu[f + "_labels"] == gpu[f + "_labels"]).mean()) for f in frames]
            depth = []
            for f in frames:
                a, b = cpu[f + "_depth"], gpu[f + "_depth"]
                both = (a > 0) & (b > 0)
                depth.append((int((both & (np.abs(a - b) > 1e-5)).sum()), float(np.abs(a - b)[both].max())))
            rgb = [psnr(cpu[f + "_rgb"], gpu[f + "_rgb"]) for f in frames]
            print(
                f"{samples} shadow sample(s), {len(frames)} views: labels equal on {100 * min(labels):.4f}% of the pixels of the "
                f"worst view; depth beyond 1e-5 m on at most {max(d[0] for d in depth)} pixels a view (largest difference "
                f"{max(d[1] for d in depth):.1e} m); RGB PSNR {min(rgb):.1f} dB worst view, {np.mean(rgb):.1f} mean"
            )


if __name__ == "__main__":
    main()

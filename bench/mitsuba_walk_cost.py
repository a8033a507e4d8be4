"""Which part of ``cutout_path`` costs: bench/mitsuba_frame_cost.py with the walks past cut-out
texels replaced by plain ray casts. MODE: ``full`` (as shipped), ``no_may_cut`` (every hit's
opacity looked up), ``no_walk`` (camera and bounce rays stop at cut texels), ``no_shadow_walk``
(shadow rays stop there), ``neither`` (Mitsuba's ``path``, in the same Python integrator). Only
``full`` gives correct images; the others measure what the walks cost. Prints figures.

    python bench/mitsuba_walk_cost.py MODE RUN_DIR [mitsuba_frame_cost.py's options]
"""

import runpy
import sys
from pathlib import Path

from agrisim.plugins.render.mitsuba import integrator as cut

MODES = ("full", "no_may_cut", "no_walk", "no_shadow_walk", "neither")
mode = sys.argv.pop(1) if len(sys.argv) > 1 else ""
if mode not in MODES:
    print(f"mitsuba_walk_cost.py: MODE must be one of {', '.join(MODES)}", file=sys.stderr)
    sys.exit(2)
base = cut._integrator_class


def patched() -> type:
    cls = base()

    class Probe(cls):
        pass

    if mode in ("no_walk", "neither"):
        Probe._kept = lambda self, scene, ray, active, coherent=False: (
            scene.ray_intersect_preliminary(ray, coherent=coherent, active=active),
            ray,
        )
    if mode in ("no_shadow_walk", "neither"):
        Probe._visible = lambda self, scene, ray, target, active: active & ~scene.ray_test(ray, active)
    if mode == "no_may_cut":
        Probe._may_cut = staticmethod(lambda pi, active: active & pi.is_valid())
    return Probe


cut._integrator_class = patched
print("mode", mode)
here = Path(__file__).parent
sys.argv[0] = str(here / "mitsuba_frame_cost.py")
sys.path.insert(0, str(here))
runpy.run_path(sys.argv[0], run_name="__main__")

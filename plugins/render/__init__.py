"""Renderers: ``raycast`` (exact ray tracing on Dr.Jit: Embree on the CPU, OptiX on GPUs), ``mitsuba`` (path tracing) and ``pybullet`` (TinyRenderer).

Each module registers its backend through the ``agrisim_renderers`` hook and an entry point in
agrisim's ``pyproject.toml``, exactly as a third-party plugin would.
"""

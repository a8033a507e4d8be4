"""Renderers: ``raycast`` (Open3D ``RaycastingScene`` on Embree, CPU) and ``pybullet`` (TinyRenderer).

Each module registers its backend through the ``agrisim_renderers`` hook and an entry point in
agrisim's ``pyproject.toml``, exactly as a third-party plugin would.
"""

"""The one image type: a Frame's stored form is what the run directory reads back."""

from __future__ import annotations

import io

import numpy as np
from PIL import Image

from agrisim.interfaces import Frame


def _frame(depth: np.ndarray) -> Frame:
    h, w = depth.shape
    return Frame(np.zeros((h, w, 3), np.uint8), np.zeros((h, w), np.uint8), depth)


def test_stored_depth_is_the_png_read_back_as_open3d_reads_it() -> None:
    rng = np.random.default_rng(3)
    depth = rng.uniform(0.0, 70.0, (40, 50)).astype(np.float32)  # past 65.535 m saturates
    depth[rng.random(depth.shape) < 0.2] = 0.0  # no hit
    frame = _frame(depth)
    buf = io.BytesIO()
    Image.fromarray(frame.depth_mm()).save(buf, format="PNG")
    png = np.array(Image.open(io.BytesIO(buf.getvalue())))
    assert png.dtype == np.uint16
    # Open3D's depth_scale = 1000: float32 millimetres / 1000
    as_read = png.astype(np.float32) / np.float32(1000.0)
    stored = frame.stored()
    assert stored.depth.dtype == np.float32
    assert np.array_equal(stored.depth, as_read)
    # storing twice changes nothing: a resumed run's frames round-trip exactly
    assert np.array_equal(stored.stored().depth, stored.depth)
    assert np.array_equal(stored.depth_mm(), png)
    assert np.array_equal(stored.depth == 0, depth == 0)
    assert np.max(np.abs(stored.depth[depth < 65.0] - depth[depth < 65.0])) <= 0.0005 + 1e-5


def test_copy_is_deep() -> None:
    frame = _frame(np.ones((4, 5), np.float32))
    frame.instances = np.ones((4, 5), np.uint16)
    copy = frame.copy()
    for name in ("rgb", "labels", "depth", "instances"):
        getattr(frame, name)[...] = 7
        assert not np.shares_memory(getattr(copy, name), getattr(frame, name))
        assert not np.all(getattr(copy, name) == 7), name


def test_radiance_is_written_as_exact_float_exr(tmp_path) -> None:  # noqa: ANN001
    """A frame's radiance goes to radiance/<frame>.exr as float32 R, G, B (another reader,
    OpenEXR's own header, names the channels) and reads back bit for bit, HDR values too."""
    import OpenEXR

    from agrisim.files import layout
    from agrisim.files.exr import read_exr
    from agrisim.plugins.sinks.dataset.writer import write_frame

    rng = np.random.default_rng(4)
    radiance = (rng.random((6, 7, 3)) ** 3 * 50.0).astype(np.float32)  # above 1: not clipped
    frame = Frame(
        np.zeros((6, 7, 3), np.uint8), np.zeros((6, 7), np.uint8), np.ones((6, 7), np.float32), radiance=radiance
    )
    write_frame(tmp_path, "r1_000", frame, None)
    path = layout.radiance(tmp_path, "r1_000")
    assert np.array_equal(read_exr(path), radiance)
    with OpenEXR.File(str(path), separate_channels=True) as f:
        channels = {name: c.pixels for name, c in f.channels().items()}
    assert sorted(channels) == ["B", "G", "R"]
    assert all(p.dtype == np.float32 for p in channels.values())
    assert np.array_equal(np.dstack([channels["R"], channels["G"], channels["B"]]), radiance)
    assert np.array_equal(frame.copy().radiance, radiance) and frame.copy().radiance is not radiance

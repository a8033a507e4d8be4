"""The dataset's PNG encoder (agrisim.files.png) against a second library: what Pillow decodes
from its files is the image that was encoded, pixel for pixel, for every kind it writes."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

from agrisim.files.png import encode_png


def _decode(data: bytes) -> Image.Image:
    Image.open(io.BytesIO(data)).verify()  # chunk CRCs and structure
    return Image.open(io.BytesIO(data))


@pytest.mark.parametrize(
    "shape, dtype, mode",
    [
        ((7, 5), np.uint8, "L"),
        ((7, 5, 3), np.uint8, "RGB"),
        ((7, 5, 4), np.uint8, "RGBA"),
        ((7, 5, 2), np.uint8, "LA"),
        ((6, 9), np.uint16, "I;16"),
        ((1, 1), np.uint16, "I;16"),
        ((1, 1, 3), np.uint8, "RGB"),
    ],
)
def test_pixels_read_back(shape: tuple[int, ...], dtype: type, mode: str) -> None:
    rng = np.random.default_rng(len(shape) * 100 + shape[0])
    image = rng.integers(0, np.iinfo(dtype).max, shape, dtype=dtype, endpoint=True)
    image.flat[0], image.flat[-1] = np.iinfo(dtype).max, 0  # both ends of the range
    decoded = _decode(encode_png(image))
    assert decoded.mode == mode
    assert decoded.size == (shape[1], shape[0])
    np.testing.assert_array_equal(np.asarray(decoded), image)


def test_strided_and_little_endian_input() -> None:
    base = np.arange(40 * 30, dtype=np.uint16).reshape(40, 30) * 53
    view = base[::2, 1::3]  # not contiguous
    np.testing.assert_array_equal(np.asarray(_decode(encode_png(view))), view)
    big = base.astype(">u2")
    np.testing.assert_array_equal(np.asarray(_decode(encode_png(big))), base)


def test_indexed_colour() -> None:
    rng = np.random.default_rng(3)
    palette = rng.integers(0, 256, (256, 3), dtype=np.uint8)
    index = rng.integers(0, 256, (8, 11), dtype=np.uint8)
    decoded = _decode(encode_png(index, palette))
    assert decoded.mode == "P"
    np.testing.assert_array_equal(np.asarray(decoded), index)
    np.testing.assert_array_equal(np.asarray(decoded.convert("RGB")), palette[index])


def test_rendered_frame_same_pixels_as_pillow(tmp_path) -> None:
    """A smooth image with edges (what renders look like): same pixels as Pillow's own PNG."""
    y, x = np.mgrid[0:120, 0:160]
    image = np.stack([x * 255 // 159, y * 255 // 119, ((x // 16 + y // 16) % 2) * 200], axis=-1).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG")
    ours = np.asarray(_decode(encode_png(image)))
    np.testing.assert_array_equal(ours, np.asarray(Image.open(buf)))


@pytest.mark.parametrize(
    "image, palette",
    [
        (np.zeros((4, 4), np.float32), None),
        (np.zeros((4, 4), np.int16), None),
        (np.zeros((4, 4, 5), np.uint8), None),
        (np.zeros((0, 4), np.uint8), None),
        (np.zeros(4, np.uint8), None),
        (np.zeros((4, 4), np.uint16), np.zeros((256, 3), np.uint8)),
        (np.zeros((4, 4), np.uint8), np.zeros((257, 3), np.uint8)),
    ],
)
def test_refuses_what_png_cannot_hold(image: np.ndarray, palette: np.ndarray | None) -> None:
    with pytest.raises(ValueError):
        encode_png(image, palette)

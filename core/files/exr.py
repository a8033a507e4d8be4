"""Float images in OpenEXR (the ``openexr`` bindings): what renderers and compositing tools
exchange linear light and depth in. 32-bit float channels, ZIP (lossless) compression: what is
written reads back bit for bit."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from agrisim.errors import UserError
from agrisim.files.atomic import write_through


def write_exr(path: Path, image: np.ndarray) -> None:
    """Write an H x W x 3 float image as the channels R, G, B (or an H x W one as Y) to
    ``path``, atomically."""
    import OpenEXR

    data = np.ascontiguousarray(image, np.float32)
    if data.ndim == 3 and data.shape[2] == 3:
        channels = {"RGB": data}
    elif data.ndim == 2:
        channels = {"Y": data}
    else:
        raise ValueError(f"an EXR image must be H x W or H x W x 3, got {data.shape}")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}

    def write(tmp: str) -> bool:
        with OpenEXR.File(header, channels) as f:
            f.write(tmp)
        return True

    write_through(Path(path), write)


def read_exr(path: Path) -> np.ndarray:
    """The image :func:`write_exr` wrote (H x W x 3 or H x W float32)."""
    import OpenEXR

    try:
        with OpenEXR.File(str(path)) as f:
            channels = f.channels()
            if "RGB" in channels:
                return np.asarray(channels["RGB"].pixels, np.float32)
            if "Y" in channels:
                return np.asarray(channels["Y"].pixels, np.float32)
            names = ", ".join(sorted(channels))
    except (OSError, RuntimeError) as exc:
        raise UserError(f"{path}: not a readable OpenEXR image ({exc})") from None
    raise UserError(f"{path}: has channels {names}, not RGB or Y")

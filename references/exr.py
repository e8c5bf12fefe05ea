"""OpenEXR I/O (float32, ZIP), written atomically: a temporary file in the same folder renamed
into place, so a reader never sees a half-written image."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import OpenEXR


def write_exr(path: Path | str, channels: dict[str, np.ndarray], header: dict | None = None) -> None:
    """channels: name -> (H, W) array, or 'RGB' -> (H, W, 3). Values are stored as float32."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    h = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    h.update(header or {})
    data = {k: np.ascontiguousarray(v, np.float32) for k, v in channels.items()}
    fd, tmp = tempfile.mkstemp(suffix=".exr.part", dir=path.parent)
    os.close(fd)
    try:
        OpenEXR.File(h, data).write(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def read_exr(path: Path | str) -> tuple[dict, dict[str, np.ndarray]]:
    """(header, channel name -> (H, W) float32 array)."""
    f = OpenEXR.File(str(path), separate_channels=True)
    return f.header(), {k: v.pixels for k, v in f.channels().items()}

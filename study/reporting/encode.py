"""How the reporting writes images and names: PNG and EXR bytes, the FLIP colour map, a
technique's output as an 8-bit display image, and file-name slugs of labels."""
from __future__ import annotations

import io
import re
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from references.exr import write_exr


def slug(label: str) -> str:
    return re.sub(r"[^a-z0-9]+", "_", str(label).lower()).strip("_")


def png(img8: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(img8).save(buf, format="PNG")
    return buf.getvalue()


def exr_bytes(channels: dict) -> bytes:
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "maps.exr"
        write_exr(path, channels)
        return path.read_bytes()


def magma(x: np.ndarray) -> np.ndarray:
    from matplotlib import colormaps
    return (colormaps["magma"](np.clip(x, 0, 1))[..., :3] * 255).astype(np.uint8)


def display_8bit(img: np.ndarray, output_space: str, disp) -> np.ndarray:
    """A technique's output as the 8-bit display image it was judged as (display.DisplayTransform.output)."""
    return disp.output(img, output_space)[2]

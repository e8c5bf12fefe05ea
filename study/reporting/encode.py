"""How the reporting writes images, names and records: PNG and EXR bytes, the FLIP colour map, a
technique's output as an 8-bit display image, file-name slugs of labels, and strict JSON."""
from __future__ import annotations

import io
import json
import math
import re
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from references.exr import write_exr


def strict_json(obj, infinity: str | None = None, **kw) -> str:
    """One strict JSON document: NaN (an undefined figure) becomes null, and so do infinities, or
    with `infinity="inf"` the strings "inf" and "-inf" (a PSNR of an exact image is +inf, not
    undefined; `from_strict` reads them back). Bare NaN/Infinity are not JSON: a browser's or
    jq's parser refuses the whole document."""
    def clean(o):
        if isinstance(o, float) and not math.isfinite(o):
            return None if infinity is None or math.isnan(o) else ("-" if o < 0 else "") + infinity
        if isinstance(o, dict):
            return {str(k): clean(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        return o
    return json.dumps(clean(obj), allow_nan=False, default=str, **kw)


def from_strict(obj):
    """A document strict_json(..., infinity="inf") wrote, with "inf" and "-inf" as floats again."""
    if isinstance(obj, str) and obj in ("inf", "-inf"):
        return float(obj)
    if isinstance(obj, dict):
        return {k: from_strict(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [from_strict(v) for v in obj]
    return obj


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

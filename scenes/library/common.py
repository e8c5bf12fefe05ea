"""Palette, lights and helpers shared by every built-in scene."""
from __future__ import annotations

import numpy as np

from ..description import DirectionalLight, Material, MeshSpec, Resolution, SceneObject, Transform

QUICK = Resolution(quick=(320, 180), full=(1600, 900))
BROWN = (0.35, 0.16, 0.06)
BLUE = (0.1, 0.2, 0.6)
WALL = (0.7, 0.68, 0.62)
SUN = DirectionalLight(direction=(-0.4, -1.0, -0.6), intensity=(2.2, 2.1, 1.9))
SKY = (0.18, 0.2, 0.24)


def _box(name, size, at, albedo, **kw) -> SceneObject:
    return SceneObject(name=name, mesh=MeshSpec(kind="box", size=size), material=Material(albedo=albedo),
                       transform=Transform(translate=at, **kw))


def _solid_box(name, size, at, albedo, **kw) -> list[SceneObject]:
    """A box as one object per face orientation, so its creases are object boundaries (see
    scenes/library/geometry.py); `kw` goes to Transform (rotate_axis, rotate_deg)."""
    from . import geometry as g
    return g.surface_objects(name, g.box(size), Material(albedo=albedo), Transform(translate=at, **kw))


def _shifted(obj: SceneObject, offset, prefix: str = "") -> SceneObject:
    """The same object moved by `offset` (added after its own rotation) and renamed."""
    t = obj.transform
    at = tuple(float(a + b) for a, b in zip(t.translate, offset))
    return obj.model_copy(update={"name": prefix + obj.name,
                                  "transform": t.model_copy(update={"translate": at})})


def _text_texture() -> np.ndarray:
    """Black letters on white, drawn in code; nearest-neighbour lookup keeps the hard edges."""
    from PIL import Image, ImageDraw, ImageFont
    img = Image.new("L", (512, 256), 255)
    draw = ImageDraw.Draw(img)
    font = ImageFont.load_default(size=44)
    for row, line in enumerate(("TEMPORAL ANTI", "ALIASING: THE", "HISTORY IS A LIE")):
        draw.text((16, 14 + row * 78), line, fill=0, font=font)
    a = np.asarray(img, np.float32)[::-1] / 255.0          # row 0 = v = 0 (bottom)
    return np.repeat(a[..., None], 3, axis=-1) * 0.85 + 0.02


def _leaf_alpha(n: int = 64) -> np.ndarray:
    """A pointed leaf silhouette: 1 inside, 0 outside (binary, as a cut-out texture is)."""
    v, u = np.meshgrid(np.linspace(0, 1, n, endpoint=False) + 0.5 / n,
                       np.linspace(0, 1, n, endpoint=False) + 0.5 / n, indexing="ij")
    half_width = 0.42 * np.sin(np.pi * v) ** 1.3
    notch = 0.04 * (np.sin(10 * np.pi * v) > 0.6)
    return (np.abs(u - 0.5) < half_width - notch).astype(np.float32)

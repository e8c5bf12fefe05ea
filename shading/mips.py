"""Mip chains of filtered textures, and their Dr.Jit tables (docs/method.md, "Texture filtering").

Each level is the box filter of the one above it. Sides are halved with floor, never below 1
(OpenGL's rule for non-power-of-two textures: 5x3 -> 2x1 -> 1x1), down to 1x1. Texel i of a
side of n' texels covers [i n / n', (i + 1) n / n') of the side of n texels above it, and its value
is the mean over that interval, texels cut by its ends weighted by the part inside (an area-weighted
box). Where n is even that is exactly the 2x2 box of texels 2i, 2i + 1; where it is odd the
texels straddle the extra one, each a box 1 + 1/n' texels wide. Every level's mean equals the
base level's for any size, since each texel above gives all of its area to the level below.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from backend import mi

FILTER_CODES = {"nearest": 0, "bilinear": 1, "trilinear": 2}


def _box_weights(n: int, m: int) -> np.ndarray:
    """(m, n) weights: row i averages [i n / m, (i + 1) n / m) of n unit texels."""
    edges = np.arange(m + 1) * (n / m)
    lo, hi = edges[:-1, None], edges[1:, None]
    j = np.arange(n)[None, :]
    overlap = np.clip(np.minimum(hi, j + 1) - np.maximum(lo, j), 0.0, None)
    return overlap / (n / m)


def next_level(tex: np.ndarray) -> np.ndarray:
    """The level below (H, W, C) `tex`: floor-halved sides (at least 1), area-weighted box."""
    h, w = tex.shape[:2]
    h2, w2 = max(1, h // 2), max(1, w // 2)
    a = np.asarray(tex, np.float64)
    out = np.einsum("ih,hwc,jw->ijc", _box_weights(h, h2), a, _box_weights(w, w2))
    return out.astype(np.float32)


def mip_chain(tex: np.ndarray) -> list[np.ndarray]:
    """Every level of (H, W, C) `tex` from the base to 1x1 (a 1x1 texture is its own chain)."""
    levels = [np.asarray(tex, np.float32)]
    while levels[-1].shape[0] > 1 or levels[-1].shape[1] > 1:
        levels.append(next_level(levels[-1]))
    return levels


@dataclass
class MipTable:
    """The filtered textures of one role, for shading.texels.filtered: per object id (index 0 =
    background) its filter code (FILTER_CODES; 0 = not filtered here), first level and level count;
    per level its offset into `data`, width and height."""
    objs: mi.UInt32     # per object: code, first level, count
    levels: mi.UInt32   # per level: offset (texels), width, height
    data: mi.Float
    bias: mi.Float      # per object: its texture's own LOD bias (scenes.description.Texture.lod_bias)


def mip_table(textures, filters, channels: int, biases=None) -> MipTable | None:
    """The MipTable of per-object (H, W, C) arrays (None where an object has none) and their
    filters (and per-object LOD biases, 0 where None), or None where no object's texture is filtered
    (its scene keeps the nearest-texel kernel it always had). Bilinear textures store the base level
    alone."""
    if not any(t is not None and f != "nearest" for t, f in zip(textures, filters)):
        return None
    objs, levels, data, pos = [0, 0, 0], [], [], 0
    stored: dict[tuple, list[int]] = {}      # objects sharing one array share its levels
    for tex, f in zip(textures, filters):
        if tex is None or f == "nearest":
            objs += [0, 0, 0]
            continue
        key = (id(tex), f)
        if key not in stored:
            t = np.asarray(tex, np.float32)
            t = t.reshape(t.shape[0], t.shape[1], -1)[..., :channels]
            if t.shape[-1] < channels:     # a grey texture is every channel's value
                t = np.repeat(t[..., :1], channels, axis=-1)
            chain = mip_chain(t) if f == "trilinear" else [t]
            stored[key] = [FILTER_CODES[f], len(levels) // 3, len(chain)]
            for lv in chain:
                levels += [pos, lv.shape[1], lv.shape[0]]
                data.append(lv.ravel())
                pos += lv.shape[0] * lv.shape[1]
        objs += stored[key]
    bias = [0.0] + [float(b or 0.0) for b in (biases or [0.0] * len(textures))]
    return MipTable(mi.UInt32(np.array(objs, np.uint32)), mi.UInt32(np.array(levels, np.uint32)),
                    mi.Float(np.concatenate(data)), mi.Float(np.array(bias, np.float32)))


def has_trilinear(scene) -> bool:
    """True where some object's texture of any role is trilinear: its raster frames depend on the
    LOD bias (a nearest or bilinear scene's do not)."""
    roles = ("texture", "metallic_roughness", "normal_map", "emission_texture", "occlusion")
    return any(getattr(getattr(o.material, r), "filter", "nearest") == "trilinear"
               for o in scene.desc.objects for r in roles)


def lod(duv_dx, duv_dy, width: int, height: int, bias: float = 0.0) -> float:
    """The level of detail OpenGL's isotropic rule gives (OpenGL 4.6, section 8.14.1): log2 of the
    longer of the pixel's two UV steps in base-level texels, plus `bias` (NumPy, one pixel; the
    Dr.Jit lookup computes the same per pixel, before clamping to the chain)."""
    sx = np.hypot(duv_dx[0] * width, duv_dx[1] * height)
    sy = np.hypot(duv_dy[0] * width, duv_dy[1] * height)
    return float(np.log2(max(sx, sy)) + bias)

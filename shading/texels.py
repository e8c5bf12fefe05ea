"""Texture lookups shared by every material term: nearest texel with wrap-around."""
from __future__ import annotations

from backend import dr, mi


def texel(table: mi.UInt32, data: mi.Float, obj, uv, channels: int, active):
    """Nearest texel of each object's texture; (has_texture, [channel values])."""
    off = dr.gather(mi.UInt32, table, obj * 3, active)
    w = dr.gather(mi.UInt32, table, obj * 3 + 1, active)
    h = dr.gather(mi.UInt32, table, obj * 3 + 2, active)
    has = active & (w > 0)
    fu, fv = uv.x - dr.floor(uv.x), uv.y - dr.floor(uv.y)
    col = dr.minimum(mi.UInt32(fu * mi.Float(w)), dr.maximum(w, 1) - 1)
    row = dr.minimum(mi.UInt32(fv * mi.Float(h)), dr.maximum(h, 1) - 1)
    idx = (off + row * w + col) * channels
    return has, [dr.gather(mi.Float, data, idx + c, has) for c in range(channels)]

"""Texture lookups shared by every material term, with wrap-around: nearest texel, or bilinear
and trilinear over a mip chain (shading.mips; docs/method.md, "Texture filtering")."""
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


def _bilinear(mips, level, uv, channels: int, active):
    """Bilinear lookup in mip level `level` (index into mips.levels), wrapping at every edge."""
    off = dr.gather(mi.UInt32, mips.levels, level * 3, active)
    w = dr.gather(mi.UInt32, mips.levels, level * 3 + 1, active)
    h = dr.gather(mi.UInt32, mips.levels, level * 3 + 2, active)
    wi, hi = mi.Int32(dr.maximum(w, 1)), mi.Int32(dr.maximum(h, 1))
    # texel centres at (i + 0.5) / w: x in [-0.5, w - 0.5) from the wrapped u
    x = (uv.x - dr.floor(uv.x)) * mi.Float(wi) - 0.5
    y = (uv.y - dr.floor(uv.y)) * mi.Float(hi) - 0.5
    x0f, y0f = dr.floor(x), dr.floor(y)
    fx, fy = x - x0f, y - y0f
    x0, y0 = mi.Int32(x0f), mi.Int32(y0f)
    x0, y0 = dr.select(x0 < 0, x0 + wi, x0), dr.select(y0 < 0, y0 + hi, y0)
    x0, y0 = dr.minimum(x0, wi - 1), dr.minimum(y0, hi - 1)
    x1, y1 = dr.select(x0 + 1 >= wi, 0, x0 + 1), dr.select(y0 + 1 >= hi, 0, y0 + 1)
    out = []
    for c in range(channels):
        def at(xx, yy):
            return dr.gather(mi.Float, mips.data, (off + mi.UInt32(yy * wi + xx)) * channels + c, active)
        top = dr.lerp(at(x0, y0), at(x1, y0), fx)
        bot = dr.lerp(at(x0, y1), at(x1, y1), fx)
        out.append(dr.lerp(top, bot, fy))
    return out


def filtered(mips, obj, uv, channels: int, active, foot=None):
    """Bilinear or trilinear lookup of each object's filtered texture (shading.mips.MipTable):
    (has_filtered, [channel values]). `foot` = ((du/dx, dv/dx, du/dy, dv/dy), lod_bias): the
    pixel's UV steps, for trilinear textures: level lambda = log2(max(|(du/dx W, dv/dx H)|,
    |(du/dy W, dv/dy H)|)) + bias + the texture's own bias, over the base level's W x H, clamped to
    the chain, and the two levels around it blended (OpenGL's LINEAR_MIPMAP_LINEAR). Without `foot`
    (the reference, the agreement check), the base level bilinearly."""
    code = dr.gather(mi.UInt32, mips.objs, obj * 3, active)
    first = dr.gather(mi.UInt32, mips.objs, obj * 3 + 1, active)
    count = dr.gather(mi.UInt32, mips.objs, obj * 3 + 2, active)
    has = active & (code > 0)
    base = _bilinear(mips, first, uv, channels, has)
    if foot is None:
        return has, base
    (dudx, dvdx, dudy, dvdy), bias = foot
    tri = has & (code == 2) & (count > 1)
    w0 = mi.Float(dr.gather(mi.UInt32, mips.levels, first * 3 + 1, tri))
    h0 = mi.Float(dr.gather(mi.UInt32, mips.levels, first * 3 + 2, tri))
    rho = dr.maximum(dr.sqrt(dr.square(dudx * w0) + dr.square(dvdx * h0)),
                     dr.sqrt(dr.square(dudy * w0) + dr.square(dvdy * h0)))
    # a step that reached no plane (a grazing neighbour ray) is as coarse as the chain goes
    rho = dr.select(dr.isfinite(rho), rho, 1e30)
    bias = bias + dr.gather(mi.Float, mips.bias, obj, tri)     # the column's and the texture's own
    lam = dr.clip(dr.log2(dr.maximum(rho, 1e-30)) + bias, 0.0, mi.Float(count - 1))
    l0 = mi.UInt32(dr.floor(lam))
    f = lam - mi.Float(l0)
    l1 = dr.minimum(l0 + 1, count - 1)
    fine = _bilinear(mips, first + l0, uv, channels, tri)
    coarse = _bilinear(mips, first + l1, uv, channels, tri)
    return has, [dr.select(tri, dr.lerp(a, b, f), c) for a, b, c in zip(fine, coarse, base)]


def lookup(table, data, mips, obj, uv, channels: int, active, foot=None):
    """Each object's texture by its declared filter: `texel` alone where no texture of this role
    is filtered (mips None: the kernel nearest-texel scenes always had), else `filtered` where an
    object's is and `texel` where it is not."""
    has, vals = texel(table, data, obj, uv, channels, active)
    if mips is None:
        return has, vals
    fhas, fvals = filtered(mips, obj, uv, channels, active, foot)
    return has | fhas, [dr.select(fhas, a, b) for a, b in zip(fvals, vals)]

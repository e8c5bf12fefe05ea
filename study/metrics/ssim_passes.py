"""SSIM's Dr.Jit passes for one pair (study.metrics.ssim): the separable filter passes that give the
per-channel map and, from the same filtered planes, MATLAB's volume form (its channel mixing and its
replicate-padded border frame), frozen per layout.
"""
from __future__ import annotations

import numpy as np

from backend import dr

from study.metrics import filters as jf
from study.metrics.ssim_window import channel_mixing, matlab_radius, skimage_radius


def _ssim_formula(ux, uy, uxx, uyy, uxy, c1, c2):
    vx = uxx - ux * ux
    vy = uyy - uy * uy
    vxy = uxy - ux * uy
    return ((2.0 * ux * uy + c1) * (2.0 * vxy + c2)) / ((ux * ux + uy * uy + c1) * (vx + vy + c2))


def _channel_sum(v: list, c1: float, c2: float):
    """The sum over R, G, B of each channel's SSIM map, from its five statistics (v[5c:5c + 5]:
    the two means, the two second moments and the cross moment, in _ssim_quantities' order)."""
    s = None
    for c in range(3):
        sc = _ssim_formula(*v[5 * c:5 * c + 5], c1, c2)
        s = sc if s is None else s + sc
    return s


def _frame_pixels(lay: jf.Layout, r: int):
    """(rows, cols) of the pixels within `r` of a border, rows first."""
    h, wd = lay.h, lay.w
    edge_rows = np.unique(np.r_[0:min(r, h), max(h - r, 0):h])
    mid_rows = np.arange(min(r, h), max(h - r, min(r, h)))
    edge_cols = np.unique(np.r_[0:min(r, wd), max(wd - r, 0):wd])
    ys = np.r_[np.repeat(edge_rows, wd), np.repeat(mid_rows, edge_cols.size)]
    xs = np.r_[np.tile(np.arange(wd), edge_rows.size), np.tile(edge_cols, mid_rows.size)]
    return ys, xs


def _volume_frame(lay: jf.Layout, planes: list, sigma: float, c1: float, c2: float):
    """(rows, cols, per-pixel channel sum of the volume SSIM) on the pixels within the filter radius
    of a border, where 'replicate' and 'reflect' differ: a direct 2-D window per pixel, 'replicate'
    (clamped) taps, float64."""
    ys, xs, y, x = _frame_of(lay, matlab_radius(sigma))
    return ys, xs, _volume_frame_core(lay, planes, y, x, sigma, c1, c2).numpy()


_FRAMES: dict = {}


def _frame_of(lay: jf.Layout, r: int):
    """The frame's pixels as numpy and as Dr.Jit arrays, made once per layout: arrays made afresh
    from numpy memory of varying alignment made the frozen core trace again (3 recordings per
    layout in a tiny study)."""
    if (lay, r) not in _FRAMES:
        J = jf.jit()
        ys, xs = _frame_pixels(lay, r)
        _FRAMES[(lay, r)] = (ys, xs, J.Int32(ys.astype(np.int32)), J.Int32(xs.astype(np.int32)))
    return _FRAMES[(lay, r)]


@dr.freeze
def _volume_frame_core(lay: jf.Layout, planes: list, y, x, sigma: float, c1: float, c2: float):
    # frozen: ~6000 traced operations a call, replayed (a new layout or sigma traces again)
    J = jf.jit()
    r = matlab_radius(sigma)
    w = jf.gaussian_weights(sigma, r)
    mix = channel_mixing(w)
    h, wd = lay.h, lay.w
    acc = [None] * 15
    for dy in range(-r, r + 1):
        row = J.UInt32(dr.clip(y + dy, 0, h - 1)) * lay.wg
        for dx in range(-r, r + 1):
            idx = row + J.UInt32(dr.clip(x + dx, 0, wd - 1))
            wt = float(w[dy + r] * w[dx + r])
            for c in range(3):
                a = dr.gather(J.Float64, planes[2 * c], idx)
                b = dr.gather(J.Float64, planes[2 * c + 1], idx)
                for q, v in enumerate((a, b, a * a, b * b, a * b)):
                    t = v * wt
                    k = 5 * c + q
                    acc[k] = t if acc[k] is None else acc[k] + t
    return _mixed_ssim(acc, mix, c1, c2)


def _mixed_ssim(v: list, mix: np.ndarray, c1: float, c2: float):
    """Sum over channels of SSIM after mixing the 15 per-channel statistics across channels."""
    tot = None
    for c in range(3):
        mixed = []
        for qi in range(5):
            acc = None
            for cc in range(3):
                t = v[5 * cc + qi] * float(mix[c, cc])
                acc = t if acc is None else acc + t
            mixed.append(acc)
        sc = _ssim_formula(*mixed, c1, c2)
        tot = sc if tot is None else tot + sc
    return tot


def _ssim_quantities(v):
    q = []
    for c in range(3):
        a, b = v[2 * c], v[2 * c + 1]
        q += [a, b, a * a, b * b, a * b]
    return q


@dr.freeze
def _ssim_core(lay: jf.Layout, planes: list, sigma: float, volume: bool, c1: float, c2: float):
    """(channel sum of the per-channel SSIM map, the volume form's channel sum, or that map again
    when volume is False) as flat arrays. Frozen: a 48x27 pair spent 85 % of its 85 ms in tracing
    the same passes again; they are now replayed (a new layout or argument traces again)."""
    rc, rv = skimage_radius(sigma), matlab_radius(sigma)
    shared = volume and rv == rc
    prec = "float64"
    wc = tuple(float(t) for t in jf.gaussian_weights(sigma, rc))
    filters = [jf.Filter(i, wc, "reflect") for i in range(15)]
    if volume and not shared:
        filters += [jf.Filter(i, tuple(float(t) for t in jf.gaussian_weights(sigma, rv)), "clamp")
                    for i in range(15)]
    hs = jf.hpass(lay, planes, _ssim_quantities, filters, prec)
    vs = jf.vpass(lay, hs, [jf.Filter(i, f.weights, f.border) for i, f in enumerate(filters)], prec)
    del hs
    s = _channel_sum(vs, c1, c2)
    if not volume:
        return s, s
    mix = channel_mixing(jf.gaussian_weights(sigma, rv))
    return s, _mixed_ssim(vs if shared else vs[15:], mix, c1, c2)

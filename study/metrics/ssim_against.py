"""SSIM of one image against several references (study.metrics.ssim): each image's own filtered
statistics computed once and kept in a caller's memo, the pair's cross term per pair; the same values
as study.metrics.ssim.ssim_both.
"""
from __future__ import annotations

import numpy as np

from backend import dr

from study.metrics import checks
from study.metrics import filters as jf
from study.metrics.ssim import K1, K2, check_pair
from study.metrics.ssim_passes import _channel_sum, _frame_of, _mixed_ssim
from study.metrics.ssim_window import SIGMA, channel_mixing, matlab_radius, skimage_radius
# -- one image judged against several references (a technique frame against a reference and its
# two halves; many technique frames against one reference) ------------------------------------------
# The 15 filtered statistics of a pair split into each image's own (mean and mean square per
# channel: 6 planes) and the pair's cross term (3 planes). Each filter is computed alone in the
# passes above, so the split gives the same values as ssim_both; the reference's moments are kept
# in a caller's memo and the technique's are computed once for all its references: 6 + 3 per pair
# filtered planes instead of 15 (and the volume form's border frame likewise).

def _own(v):
    return [v[0], v[1], v[2], v[0] * v[0], v[1] * v[1], v[2] * v[2]]


def _cross(v):
    return [v[0] * v[1], v[2] * v[3], v[4] * v[5]]


@dr.freeze
def _moments_core(lay: jf.Layout, planes: list, sigma: float):
    """One image's per-channel filtered mean and mean square, reflect borders: [u0, u1, u2, q0, q1, q2]."""
    wc = tuple(float(t) for t in jf.gaussian_weights(sigma, skimage_radius(sigma)))
    hs = jf.hpass(lay, planes, _own, [jf.Filter(i, wc, "reflect") for i in range(6)], "float64")
    return jf.vpass(lay, hs, [jf.Filter(i, wc, "reflect") for i in range(6)], "float64")


@dr.freeze
def _frame_moments_core(lay: jf.Layout, planes: list, y, x, sigma: float):
    """The same over the border frame's pixels with 'replicate' taps (the volume form's)."""
    return _frame_sums(lay, planes, y, x, sigma, _own)


@dr.freeze
def _pair_core(lay: jf.Layout, pairs: list, mr: list, mx: list, sigma: float, volume: bool, c1: float, c2: float):
    """The pair's cross term and both SSIM forms' channel sums (as _ssim_core)."""
    wc = tuple(float(t) for t in jf.gaussian_weights(sigma, skimage_radius(sigma)))
    hs = jf.hpass(lay, pairs, _cross, [jf.Filter(i, wc, "reflect") for i in range(3)], "float64")
    xy = jf.vpass(lay, hs, [jf.Filter(i, wc, "reflect") for i in range(3)], "float64")
    return _combine(mr, mx, xy, sigma, volume, c1, c2)


@dr.freeze
def _frame_pair_core(lay: jf.Layout, pairs: list, y, x, mr: list, mx: list, sigma: float, c1: float, c2: float):
    xy = _frame_sums(lay, pairs, y, x, sigma, _cross)
    return _combine(mr, mx, xy, sigma, True, c1, c2)[1]


def _frame_sums(lay: jf.Layout, planes: list, y, x, sigma: float, quantities):
    """Direct 2-D windows at the frame pixels (y, x), clamped taps, in _volume_frame_core's order."""
    J = jf.jit()
    r = matlab_radius(sigma)
    w = jf.gaussian_weights(sigma, r)
    h, wd = lay.h, lay.w
    acc = None
    for dy in range(-r, r + 1):
        row = J.UInt32(dr.clip(y + dy, 0, h - 1)) * lay.wg
        for dx in range(-r, r + 1):
            idx = row + J.UInt32(dr.clip(x + dx, 0, wd - 1))
            wt = float(w[dy + r] * w[dx + r])
            terms = [v * wt for v in quantities([dr.gather(J.Float64, p, idx) for p in planes])]
            acc = terms if acc is None else [a + t for a, t in zip(acc, terms)]
    return acc


def _combine(mr: list, mx: list, xy: list, sigma: float, volume: bool, c1: float, c2: float):
    """(per-channel SSIM channel sum, volume form's) from the reference's moments `mr`, the
    technique's `mx` and the cross terms, in _ssim_core's order (a = reference, b = technique)."""
    stats = []
    for c in range(3):
        stats += [mr[c], mx[c], mr[3 + c], mx[3 + c], xy[c]]
    s = _channel_sum(stats, c1, c2)
    if not volume:
        return s, s
    return s, _mixed_ssim(stats, channel_mixing(jf.gaussian_weights(sigma, matlab_radius(sigma))), c1, c2)


def _image(lay: jf.Layout, img8: np.ndarray, sigma: float, volume: bool, memo: dict | None) -> tuple:
    """(planes, moments, frame moments or None) of one image, kept in `memo` when given."""
    key = ("ssim", sigma, volume, img8.shape, img8.dtype.str)
    if memo is not None and key in memo:
        return memo[key]
    planes = [lay.upload(img8[..., c], "float64") for c in range(3)]
    frame = None
    if volume:
        _, _, y, x = _frame_of(lay, matlab_radius(sigma))
        frame = _frame_moments_core(lay, planes, y, x, sigma)
    out = (planes, _moments_core(lay, planes, sigma), frame)
    if memo is not None:
        memo[key] = out
    return out


def ssim_against(refs8: list, x8: np.ndarray, memos: list | None = None, sigma: float = SIGMA,
                 volume: bool = True, data_range: float | None = None) -> list:
    """`ssim_both` of one image against several references, the image's own moments computed once.

    Parameters
    ----------
    refs8 : list of numpy.ndarray
        The references (e.g. a reference and its two halves), each as `ssim_both`'s `ref8`.
    x8 : numpy.ndarray
        The test image, of the references' shape and kind.
    memos : list of dict, optional
        One dict per reference, kept by the caller: the reference's moments are kept there for
        the next image judged against it. None: none kept.
    sigma : float
        The Gaussian window's standard deviation in pixels.
    volume : bool
        Compute the volume form too.
    data_range : float, optional
        As `ssim_both`, for every pair.

    Returns
    -------
    list of tuple
        One (mean, map, volume or None) per reference, the same values as `ssim_both` bit for bit.

    Raises
    ------
    ValueError
        As `ssim_both`, for any of the pairs (the message names the shapes or the problem).

    References
    ----------
    Wang et al. 2004; see `ssim_both`.
    """
    checks.positive("SSIM", "sigma", sigma)
    rc = skimage_radius(sigma)
    Ls = []
    for r8 in refs8:
        _, x8, L = check_pair(r8, x8, data_range, rc)
        Ls.append(L)
    h, w = x8.shape[:2]
    volume = volume and matlab_radius(sigma) == rc     # the shared-pass case ssim_both takes
    lay = jf.Layout(h, w)
    xp, xm, xf = _image(lay, x8, sigma, volume, None)
    out = []
    for r8, memo, L in zip(refs8, memos or [None] * len(refs8), Ls):
        c1, c2 = (K1 * L) ** 2, (K2 * L) ** 2
        r8 = np.asarray(r8)
        rp, rm, rf = _image(lay, r8, sigma, volume, memo)
        pairs = [p for c in range(3) for p in (rp[c], xp[c])]
        s, v = _pair_core(lay, pairs, rm, xm, sigma, volume, c1, c2)
        smap = lay.download(s * (1.0 / 3.0))
        mean = float(smap[rc:h - rc, rc:w - rc].mean(dtype=np.float64))
        if not volume:
            out.append((mean, smap, None))
            continue
        vmap = lay.download(v)
        ys, xs, y, x = _frame_of(lay, rc)
        vmap[ys, xs] = _frame_pair_core(lay, pairs, y, x, rf, xf, sigma, c1, c2).numpy()
        out.append((mean, smap, float(vmap.mean(dtype=np.float64) / 3.0)))
    return out

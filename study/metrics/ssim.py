"""SSIM in Dr.Jit (float64): the per-channel form the study reports and MATLAB's volume form the
thesis used, computed together from one pair of separable passes.

Per-channel (scikit-image 0.26.0 structural_similarity, gaussian_weights=True, sigma 1.5,
use_sample_covariance=False, data_range 255, K1 0.01, K2 0.03): each channel filtered by an 11-tap
Gaussian (truncate 3.5: radius int(3.5 sigma + 0.5) = 5) with scipy.ndimage 'reflect' borders; the
map is the channel mean of the SSIM maps; the scalar is the mean over channels of each map's mean
with the 5-pixel border cropped.

Volume (MATLAB `ssim` as shipped 2017-2018, on an H x W x 3 array): a 3-D Gaussian, sigma 1.5 on
all three axes, filter size 2*ceil(3 sigma)+1 = 11 (ssim.m passes FilterSize itself; imgaussfilt3's
own default 2*ceil(2 sigma)+1 = 7 does not apply), 'replicate' padding on all three axes,
C1 = (0.01 L)^2, C2 = (0.03 L)^2, C3 = C2/2 and exponents 1 (so Wang et al.'s eq. 13), L = 255 for
uint8; ssimval = mean of the map over all H*W*3 voxels, borders included. Along the channel axis
(3 samples, radius 5, replicate) the Gaussian reduces to a fixed 3x3 mixing of the channels, which
commutes with the spatial filter.

Input: two uint8 8-bit display images (data range 255, the study's), or two float images with an
explicit `data_range` (scikit-image's rule: a float image carries no range of its own, and SSIM's
constants C1, C2 scale with it, so a [0, 1] pair judged as 0..255 would score ~1 whatever it
holds). Anything else is refused up front (`data_range_of`, study.metrics.checks).

References
----------
Z. Wang, A. C. Bovik, H. R. Sheikh, E. P. Simoncelli, "Image quality assessment: from error
visibility to structural similarity", IEEE Transactions on Image Processing 13(4), 2004.
"""
from __future__ import annotations

import math

import numpy as np

from backend import dr

from study.metrics import checks
from study.metrics import filters as jf

SIGMA = 1.5
K1, K2 = 0.01, 0.03
DATA_RANGE = 255.0
SKIMAGE_TRUNCATE = 3.5
EXPECTED = "uint8 8-bit display images (data range 255), or float images with an explicit data_range"


def data_range_of(ref: np.ndarray, x: np.ndarray, data_range: float | None = None) -> float:
    """The data range L of SSIM's constants C1 = (K1 L)^2, C2 = (K2 L)^2 for a pair, checked.

    Parameters
    ----------
    ref, x : numpy.ndarray
        The reference and the test image, of one shape (checked by the caller).
    data_range : float, optional
        The span of values the images can take (e.g. 1.0 for display images in [0, 1]). Optional
        for uint8 images (255), required for float ones.

    Returns
    -------
    float
        `data_range`, or 255 for a uint8 pair without one.

    Raises
    ------
    ValueError
        If the images are neither both uint8 nor both float; if they are float and `data_range`
        is missing, or their values span more than it; if they hold NaN or Inf; if `data_range`
        is not a finite number > 0.
    """
    kinds = {a.dtype.kind if a.dtype != np.uint8 else "u8" for a in (ref, x)}
    if len(kinds) > 1 or not kinds <= {"u8", "f"}:
        what = ref.dtype if ref.dtype == x.dtype else f"{ref.dtype} and {x.dtype}"
        raise ValueError(f"SSIM expects {EXPECTED}, both of one kind; got {what}")
    if ref.dtype == np.uint8:
        return DATA_RANGE if data_range is None else checks.positive("SSIM", "data_range", data_range)
    if data_range is None:
        raise ValueError(f"SSIM of {ref.dtype} images needs an explicit data_range (1.0 for display "
                         f"images in [0, 1]): it expects {EXPECTED}")
    L = checks.positive("SSIM", "data_range", data_range)
    lo_r, hi_r = checks.finite_span("SSIM", "reference", ref)
    lo_x, hi_x = checks.finite_span("SSIM", "test image", x)
    lo, hi = min(lo_r, lo_x), max(hi_r, hi_x)
    if hi - lo > L:
        raise ValueError(f"SSIM: the images' values span [{lo:.6g}, {hi:.6g}], more than data_range {L:g}")
    return L


def skimage_radius(sigma: float = SIGMA) -> int:
    """Radius of scikit-image's Gaussian window, int(truncate * sigma + 0.5), truncate 3.5.

    Parameters
    ----------
    sigma : float
        The Gaussian's standard deviation in pixels.

    Returns
    -------
    int
        5 for sigma 1.5 (an 11-tap window).
    """
    return int(SKIMAGE_TRUNCATE * sigma + 0.5)


def matlab_radius(sigma: float = SIGMA) -> int:
    """Radius of MATLAB ssim's Gaussian window, ceil(3 sigma) (FilterSize 2 ceil(3 sigma) + 1).

    Parameters
    ----------
    sigma : float
        The Gaussian's standard deviation in pixels.

    Returns
    -------
    int
        5 for sigma 1.5 (an 11-tap window).
    """
    return int(math.ceil(3 * sigma))


def channel_mixing(weights: np.ndarray, channels: int = 3) -> np.ndarray:
    """The 1-D filter along the channel axis, 'replicate' padding, as a channels x channels matrix.

    Parameters
    ----------
    weights : numpy.ndarray
        The filter's taps (odd length, centre in the middle).
    channels : int
        Number of channels.

    Returns
    -------
    numpy.ndarray
        M with M[c, c'] the weight channel c' gets in output channel c.
    """
    r = len(weights) // 2
    m = np.zeros((channels, channels))
    for c in range(channels):
        for k in range(-r, r + 1):
            m[c, jf.border_index(c + k, channels, "clamp")] += weights[k + r]
    return m


def check_pair(ref, x, data_range: float | None = None, radius: int | None = None):
    """A pair SSIM can judge, as arrays, with its data range.

    Parameters
    ----------
    ref, x : array_like
        Reference and test image: H x W x 3 of one shape, uint8 8-bit display images or float
        images with `data_range`.
    data_range : float, optional
        The span of values the images can take: 255 for uint8 when omitted, required for float.
    radius : int, optional
        The window's radius r: the images must be at least 2 r + 1 pixels on each side. None:
        any size of at least 1 x 1 (the volume form).

    Returns
    -------
    ref, x : numpy.ndarray
        The inputs as arrays (no copy).
    data_range : float
        As `data_range_of`.

    Raises
    ------
    ValueError
        If the shapes differ (both named) or are not H x W x 3, the images are smaller than the
        window, or `data_range_of` refuses them.
    """
    ref, x = checks.as_array("SSIM", "reference", ref), checks.as_array("SSIM", "test image", x)
    checks.rgb("SSIM", ref, x)
    h, w = ref.shape[:2]
    if radius is not None and min(h, w) < 2 * radius + 1:
        raise ValueError(f"SSIM needs images of at least {2 * radius + 1}x{2 * radius + 1} pixels, got {w}x{h}")
    if min(h, w) < 1:
        raise ValueError(f"SSIM needs images of at least 1x1 pixel, got {w}x{h}")
    return ref, x, data_range_of(ref, x, data_range)


def _ssim_formula(ux, uy, uxx, uyy, uxy, c1, c2):
    vx = uxx - ux * ux
    vy = uyy - uy * uy
    vxy = uxy - ux * uy
    return ((2.0 * ux * uy + c1) * (2.0 * vxy + c2)) / ((ux * ux + uy * uy + c1) * (vx + vy + c2))


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
    s = None
    for c in range(3):
        sc = _ssim_formula(*vs[5 * c:5 * c + 5], c1, c2)
        s = sc if s is None else s + sc
    if not volume:
        return s, s
    mix = channel_mixing(jf.gaussian_weights(sigma, rv))
    return s, _mixed_ssim(vs if shared else vs[15:], mix, c1, c2)


def ssim_both(ref8: np.ndarray, x8: np.ndarray, sigma: float = SIGMA, volume: bool = True,
              data_range: float | None = None):
    """Per-channel SSIM (scikit-image's form), its map, and MATLAB's volume SSIM, in one pass.

    Both forms use the same 11-tap Gaussian (radius 5 for sigma 1.5 in both rules), so away from the
    borders their filtered statistics coincide: the Dr.Jit passes compute them once (with
    scikit-image's reflect borders) and the volume form's 5-pixel frame, where 'replicate' differs,
    is recomputed directly.

    Parameters
    ----------
    ref8, x8 : numpy.ndarray
        Reference and test image, H x W x 3 of one shape, H and W at least 2 r + 1 (11 for sigma
        1.5): uint8 8-bit display images, or float images with `data_range`.
    sigma : float
        The Gaussian window's standard deviation in pixels (1.5 in Wang et al. 2004).
    volume : bool
        Compute the volume form too.
    data_range : float, optional
        The span of values the images can take: 255 for uint8 when omitted, required for float.

    Returns
    -------
    mean : float
        The per-channel mean SSIM: the mean over channels of each channel map's mean, the
        r-pixel border cropped (scikit-image 0.26.0 structural_similarity, gaussian_weights=True,
        use_sample_covariance=False, K1 0.01, K2 0.03).
    map : numpy.ndarray
        (H, W) float64, the channel mean of the per-channel SSIM maps (1 = identical).
    volume : float or None
        MATLAB's ssim of the H x W x 3 array as one volume (the thesis's SSIM), or None.

    Raises
    ------
    ValueError
        If the images differ in shape, are not H x W x 3, are smaller than the window, are not
        both uint8 or both float, are float without `data_range` or span more than it, or hold
        NaN/Inf (`data_range_of`).

    References
    ----------
    Wang et al. 2004 (eq. 13, the Gaussian-windowed form of their section III-B); MATLAB R2018
    ``ssim`` for the volume form, as used in Oliveros 2018, Improved Sampling for Temporal
    Anti-Aliasing, Lund University.
    """
    checks.positive("SSIM", "sigma", sigma)
    rc = skimage_radius(sigma)
    ref8, x8, L = check_pair(ref8, x8, data_range, rc)
    h, w = ref8.shape[:2]
    rv = matlab_radius(sigma)
    shared = volume and rv == rc
    lay = jf.Layout(h, w)
    prec = "float64"
    planes = []
    for c in range(3):
        planes += [lay.upload(ref8[..., c], prec), lay.upload(x8[..., c], prec)]

    c1, c2 = (K1 * L) ** 2, (K2 * L) ** 2
    s, v = _ssim_core(lay, planes, sigma, volume, c1, c2)
    smap = lay.download(s * (1.0 / 3.0))
    mean = float(smap[rc:h - rc, rc:w - rc].mean(dtype=np.float64))
    if not volume:
        return mean, smap, None
    vmap = lay.download(v)
    if shared:
        ys, xs, vals = _volume_frame(lay, planes, sigma, c1, c2)
        vmap[ys, xs] = vals
    return mean, smap, float(vmap.mean(dtype=np.float64) / 3.0)


def ssim(ref8: np.ndarray, x8: np.ndarray, sigma: float = SIGMA,
         data_range: float | None = None) -> tuple[float, np.ndarray]:
    """Per-channel mean SSIM and its map, as scikit-image 0.26.0 computes them.

    Parameters
    ----------
    ref8, x8 : numpy.ndarray
        Reference and test image, H x W x 3 of one shape, at least 11 x 11 for sigma 1.5: uint8
        8-bit display images, or float images with `data_range`.
    sigma : float
        The Gaussian window's standard deviation in pixels.
    data_range : float, optional
        The span of values the images can take: 255 for uint8 when omitted, required for float
        (e.g. 1.0 for display images in [0, 1]).

    Returns
    -------
    mean : float
        Mean SSIM, the r-pixel border cropped.
    map : numpy.ndarray
        (H, W) float64, the channel mean of the per-channel maps.

    Raises
    ------
    ValueError
        As `ssim_both`: float input without `data_range` among them.

    References
    ----------
    Wang et al. 2004; scikit-image 0.26.0 ``skimage.metrics.structural_similarity``
    (gaussian_weights=True, sigma=1.5, use_sample_covariance=False, K1=0.01, K2=0.03).
    """
    mean, smap, _ = ssim_both(ref8, x8, sigma, volume=False, data_range=data_range)
    return mean, smap


def ssim_volume(ref8: np.ndarray, x8: np.ndarray, sigma: float = SIGMA, data_range: float | None = None) -> float:
    """MATLAB's SSIM of two H x W x 3 arrays as volumes (the thesis's form); any H, W >= 1.

    Parameters
    ----------
    ref8, x8 : numpy.ndarray
        Reference and test image, H x W x 3 of one shape: uint8 8-bit display images, or float
        images with `data_range`.
    sigma : float
        The 3-D Gaussian's standard deviation (on all three axes).
    data_range : float, optional
        The span of values the images can take: 255 for uint8 when omitted, required for float.

    Returns
    -------
    float
        The mean of the volume SSIM map over all H * W * 3 voxels, borders included.

    Raises
    ------
    ValueError
        As `ssim_both`, except that any size of at least 1 x 1 is accepted.

    References
    ----------
    Wang et al. 2004, eq. 13 with C3 = C2 / 2; MATLAB R2018 ``ssim`` on an H x W x 3 array
    (11 x 11 x 11 Gaussian window, 'replicate' padding), as used in Oliveros 2018, Improved
    Sampling for Temporal Anti-Aliasing, Lund University.
    """
    checks.positive("SSIM", "sigma", sigma)
    ref8, x8, L = check_pair(ref8, x8, data_range)
    if min(ref8.shape[:2]) >= 2 * skimage_radius(sigma) + 1:
        return ssim_both(ref8, x8, sigma, volume=True, data_range=L)[2]
    # Smaller than the window: every pixel is a border pixel, computed directly.
    lay = jf.Layout(*ref8.shape[:2])
    planes = []
    for c in range(3):
        planes += [lay.upload(ref8[..., c], "float64"), lay.upload(x8[..., c], "float64")]
    _, _, vals = _volume_frame(lay, planes, sigma, (K1 * L) ** 2, (K2 * L) ** 2)
    return float(vals.mean(dtype=np.float64) / 3.0)


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
    s = None
    for c in range(3):
        sc = _ssim_formula(*stats[5 * c:5 * c + 5], c1, c2)
        s = sc if s is None else s + sc
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

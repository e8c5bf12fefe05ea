"""FLIP (Andersson et al. 2020) and HDR-FLIP (Andersson et al. 2021) in Dr.Jit, float32, computed as
flip-evaluator 1.7 computes them (its C++ path, read in NVlabs/flip FLIP.h), with its defaults:
67.02 pixels per degree (0.7 m from a 0.7 m wide, 3840 pixel display), ACES tone mapper for HDR.

LDR: sRGB input -> linear, clamped to [0, 1] -> YCxCz. Colour pipeline: the CSF filters (Y and Cx
one Gaussian each, Cz a sum of two, applied as two separable Gaussians of square-rooted amplitude)
with clamp-to-edge borders, back to linear RGB clamped to [0, 1], CIELab, Hunt adjustment, HyAB
distance, ^0.7 and the two-segment remap to [0, 1]. Feature pipeline: Gaussian, first and second
Gaussian-derivative filters on the normalised Y, edge and point magnitudes, the larger difference
/ sqrt(2), ^0.5. Per pixel: colour ^ (1 - feature).
HDR: exposures c_start..c_stop from the reference (ACES's 0.85 crossing over the max and the median
luminance, the median at least FLT_EPSILON as 1.7 does), ceil(c_stop - c_start) of them (at least
2); each exposure is tone-mapped, clamped and scored as LDR; the map is the per-pixel maximum.

Filters accumulate in the C++'s tap order with separate multiply and add, and host-side constants
(filter weights, exposures) follow its float32 arithmetic. The mean is taken in float64 (the C++ sums
the map in float32, one pixel after another, which at 1600x900 is itself off by ~1e-6).

Input (checked up front, `check_pair`): LDR takes sRGB display images, float in [0, 1] or uint8
(read as value / 255, as flip-evaluator reads an 8-bit PNG); HDR takes linear float images, >= 0.
NaN and Inf are refused, as are an 8-bit image judged against a float one and images of different
shapes, each with the image and the problem named.

References
----------
P. Andersson, J. Nilsson, T. Akenine-Moller, M. Oskarsson, K. Astrom, M. D. Fairchild, "FLIP: A
Difference Evaluator for Alternating Images", Proc. ACM Comput. Graph. Interact. Tech. 3(2), 2020.
P. Andersson, J. Nilsson, P. Shirley, T. Akenine-Moller, "Visualizing Errors in Rendered High
Dynamic Range Images", Eurographics 2021 Short Papers.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from study.metrics import checks
from study.metrics import filters as jf
from backend import dr
from study.metrics.flip_colour import ACES, _f32_of, _pow_type, _srgb_to_linear, consts, f32
from study.metrics.flip_passes import _between, _filtered, _planes
MODES = ("LDR", "HDR")
LDR_EXPECTED = "sRGB display images, float in [0, 1] or uint8"
HDR_EXPECTED = "linear float images with values >= 0"


def check_pair(ref, x, mode: str) -> tuple[np.ndarray, np.ndarray]:
    """A pair FLIP can judge in `mode`, as arrays (uint8 LDR images as float32 value / 255).

    Parameters
    ----------
    ref, x : array_like
        Reference and test image, H x W x 3 of one shape. LDR: sRGB display images, float in
        [0, 1] or uint8; HDR: linear float images, >= 0.
    mode : {'LDR', 'HDR'}

    Returns
    -------
    tuple of numpy.ndarray
        (ref, x): the inputs themselves where they are float arrays already.

    Raises
    ------
    ValueError
        If `mode` is neither; if the shapes differ or are not H x W x 3; if one image is 8-bit
        and the other float; if an image holds NaN or Inf; LDR: if an image is integer but not
        uint8, or float outside [0, 1]; HDR: if an image is not float, or holds a negative value.
        The message names the image and the values found.
    """
    if mode not in MODES:
        raise ValueError(f"FLIP mode must be 'LDR' (display images) or 'HDR' (linear), not {mode!r}")
    names = ("reference", "test image")
    ref, x = (checks.as_array(f"{mode}-FLIP", n, a) for n, a in zip(names, (ref, x)))
    checks.rgb(f"{mode}-FLIP", ref, x)
    if mode == "LDR":
        checks.same_kind(f"{mode}-FLIP", ref, x, LDR_EXPECTED)
    return check_image(mode, names[0], ref), check_image(mode, names[1], x)


def check_image(mode: str, name: str, a: np.ndarray) -> np.ndarray:
    """One image FLIP can judge in `mode` (its dtype and values; shapes are `check_pair`'s).

    Parameters
    ----------
    mode : {'LDR', 'HDR'}
    name : str
        What the image is (``"reference"``, ``"test image"``), for the message.
    a : numpy.ndarray
        The image.

    Returns
    -------
    numpy.ndarray
        `a` itself, or for a uint8 LDR image float32 value / 255.

    Raises
    ------
    ValueError
        As `check_pair`, for this image.
    """
    if mode not in MODES:
        raise ValueError(f"FLIP mode must be 'LDR' (display images) or 'HDR' (linear), not {mode!r}")
    metric = f"{mode}-FLIP"
    if mode == "LDR":
        if a.dtype == np.uint8:
            return a.astype(f32) / f32(255.0)
        if a.dtype.kind != "f":
            raise ValueError(f"{metric}: the {name} is {a.dtype}; it expects {LDR_EXPECTED}")
        lo, hi = checks.finite_span(metric, name, a)
        if lo < 0 or hi > 1:
            raise ValueError(f"{metric}: the {name}'s values span [{lo:.6g}, {hi:.6g}]; it expects {LDR_EXPECTED} "
                             f"(linear HDR images: mode 'HDR')")
        return a
    if a.dtype.kind != "f":
        raise ValueError(f"{metric}: the {name} is {a.dtype}; it expects {HDR_EXPECTED}")
    lo, _ = checks.finite_span(metric, name, a)
    if lo < 0:
        raise ValueError(f"{metric}: the {name} holds negative values (down to {lo:.6g}); it expects {HDR_EXPECTED}")
    return a


def exposures(ref_lin: np.ndarray) -> tuple[f32, f32, int]:
    """HDR-FLIP's exposure range, as flip-evaluator 1.7 derives it from the reference.

    Parameters
    ----------
    ref_lin : numpy.ndarray
        The linear reference, H x W x 3, float, >= 0.

    Returns
    -------
    c_start : numpy.float32
        log2 of the exposure at which ACES maps the brightest luminance to 0.85.
    c_stop : numpy.float32
        The same for the median luminance (at least FLT_EPSILON).
    count : int
        ceil(c_stop - c_start) exposures, at least 2.

    Raises
    ------
    ValueError
        If the reference is not float, holds NaN, Inf or negative values, or is black.

    References
    ----------
    Andersson et al. 2021, "Visualizing Errors in Rendered High Dynamic Range Images", sec. 3.
    """
    r = checks.as_array("HDR-FLIP", "reference", ref_lin)
    if r.dtype.kind != "f":
        raise ValueError(f"HDR-FLIP: the reference is {r.dtype}; it expects {HDR_EXPECTED}")
    if r.ndim != 3 or r.shape[-1] != 3:
        raise ValueError(f"HDR-FLIP needs an H x W x 3 reference, got shape {r.shape}")
    if checks.finite_span("HDR-FLIP", "reference", r)[0] < 0:
        raise ValueError(f"HDR-FLIP: the reference holds negative values; it expects {HDR_EXPECTED}")
    r = np.asarray(r, f32)
    lum = (f32(0.2126) * r[..., 0] + f32(0.7152) * r[..., 1]) + f32(0.0722) * r[..., 2]
    lum = lum.ravel()
    ymax = lum.max()
    ymed = np.partition(lum, lum.size // 2)[lum.size // 2]
    ymed = max(ymed, np.finfo(f32).eps)
    t = f32(0.85)
    a = ACES[0] - t * ACES[3]
    b = ACES[1] - t * ACES[4]
    cc = ACES[2] - t * ACES[5]
    d1 = f32(-0.5) * (b / a)
    d2 = _f32_of(math.sqrt(d1 * d1 - cc / a))
    xmax = d1 + d2
    if not ymax > 0:
        raise ValueError("HDR-FLIP: the reference image is black (no exposure range can be derived)")
    start = _f32_of(math.log2(xmax / ymax))
    stop = _f32_of(math.log2(xmax / ymed))
    if start > stop:
        raise ValueError(f"HDR-FLIP: start exposure {start} above stop exposure {stop}")
    n = int(max(f32(2.0), f32(math.ceil(stop - start))))
    return start, stop, n


def flip(ref: np.ndarray, x: np.ndarray, mode: str, ppd: float | None = None,
         memo: dict | None = None, xmemo: dict | None = None) -> tuple[float, np.ndarray]:
    """LDR-FLIP or HDR-FLIP of a test image against a reference, as flip-evaluator 1.7 computes it.

    Parameters
    ----------
    ref, x : numpy.ndarray
        Reference and test image, H x W x 3 of one shape. 'LDR': sRGB display images, float in
        [0, 1] or uint8 (read as value / 255); 'HDR': linear float images, >= 0.
    mode : {'LDR', 'HDR'}
        'HDR' judges ceil(c_stop - c_start) tone-mapped exposures (`exposures`) and keeps the
        per-pixel maximum.
    ppd : float, optional
        Pixels per degree of visual angle (`default_ppd`, about 67.02, when omitted).
    memo : dict, optional
        Kept by a caller that judges several images against this one reference (and only this
        one): the reference's half of the work (exposures, filtered planes) is kept there.
    xmemo : dict, optional
        The same for `x` judged against several references: its half at each exposure is kept
        (LDR: one; HDR: one per exposure value, shared where two references' exposures agree).

    Returns
    -------
    mean : float
        The mean of the map (in float64).
    map : numpy.ndarray
        (H, W) float32, the per-pixel FLIP error in [0, 1] (0 = no perceived difference).

    Raises
    ------
    ValueError
        If the pair is not one FLIP can judge in `mode` (`check_pair`), `ppd` is not a finite
        number > 0, or (HDR) the reference is black.

    References
    ----------
    Andersson et al. 2020, "FLIP: A Difference Evaluator for Alternating Images" (LDR);
    Andersson et al. 2021, "Visualizing Errors in Rendered High Dynamic Range Images" (HDR);
    flip-evaluator 1.7 (NVlabs/flip) for every constant and default.
    """
    ref, x = check_pair(ref, x, mode)
    return _flip(ref, x, mode, ppd, memo, xmemo)


def _flip(ref: np.ndarray, x: np.ndarray, mode: str, ppd, memo: dict | None, xmemo: dict | None):
    """`flip` of a pair already checked (`check_pair`; study.metrics.suite checks each image once
    per frame and each reference once, then judges it several times)."""
    c = consts(ppd)
    h, w = ref.shape[:2]
    lay = jf.Layout(h, w)
    memo = {} if memo is None else memo
    xmemo = {} if xmemo is None else xmemo

    def half(store, key, rgb_of):
        k = (mode, key, float(c.ppd))
        if k not in store:
            store[k] = _filtered(lay, rgb_of(), c)
        return store[k]

    def pair(key_r, rgb_of_ref, key_x, rgb_of_x):
        return _between(lay, *half(memo, key_r, rgb_of_ref), *half(xmemo, key_x, rgb_of_x), c)

    if mode == "LDR":
        def linear(img):
            return [dr.clip(_srgb_to_linear(p, _pow_type()), 0.0, 1.0) for p in _planes(lay, img)]
        err = pair("ldr", lambda: linear(ref), "ldr", lambda: linear(x))
    else:
        if ("exposures", "HDR") not in memo:
            memo[("exposures", "HDR")] = exposures(ref)
        start, stop, n = memo[("exposures", "HDR")]
        step = (stop - start) / f32(n - 1)
        x_planes = functools.cache(lambda: _planes(lay, x))    # uploaded only where a half is missing
        err = None
        for i in range(n):
            e = start + f32(i) * step
            m = float(_f32_of(2.0 ** float(e)))
            ei = pair(i, lambda: _aces(_planes(lay, ref), m), m, lambda: _aces(x_planes(), m))
            err = ei if err is None else dr.maximum(err, ei)
            dr.eval(err)
    emap = lay.download(err)
    return float(emap.mean(dtype=np.float64)), np.ascontiguousarray(emap, np.float32)


def _aces(planes, m: float):
    """Exposure 2^e (m) and FLIP's ACES fit, clamped to [0, 1]."""
    out = []
    for p in planes:
        v = p * dr.opaque(type(p), m)     # a literal would compile a kernel per exposure (per reference)
        num = (v * v) * float(ACES[0]) + v * float(ACES[1]) + float(ACES[2])
        den = (v * v) * float(ACES[3]) + v * float(ACES[4]) + float(ACES[5])
        out.append(dr.clip(num / den, 0.0, 1.0))
    return out

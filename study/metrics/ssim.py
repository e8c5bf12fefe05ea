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

import numpy as np

from study.metrics import checks
from study.metrics import filters as jf
from study.metrics.ssim_passes import _ssim_core, _volume_frame
from study.metrics.ssim_window import SIGMA, matlab_radius, skimage_radius

K1, K2 = 0.01, 0.03
DATA_RANGE = 255.0
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

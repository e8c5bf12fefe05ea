"""Image metrics (Oliveros 2018, §3.9; Wang 2004 SSIM; Andersson 2020 FLIP): on 8-bit display images as the thesis did, plus FLIP and a
relative MSE in linear HDR so tone mapping cannot hide errors.

  MSE, RMSD        over all pixels and channels of the 8-bit images
  PSNR             10 log10(255^2 / MSE), +inf when MSE = 0
  SNR              10 log10(sum ref^2 / sum (ref - x)^2)  (MATLAB psnr's second output)
  SSIM             Wang et al.: Gaussian window sigma 1.5, K1 0.01, K2 0.03, population covariance,
                   data_range 255, per channel, as scikit-image 0.26.0 computes it (study.metrics.ssim)
  SSIM volume      MATLAB's ssim on the H x W x 3 array as one volume, the thesis's form (study.metrics.ssim);
                   a scalar, for comparison with the thesis's SSIM column only
  FLIP LDR / HDR   as flip-evaluator 1.7 computes them, on the display images and on the linear ones
                   (study.metrics.flip)
  relMSE (HDR)     mean((x - r)^2 / (r^2 + 0.01)) in linear HDR

SSIM and FLIP run in Dr.Jit (study.metrics.filters); `impl="library"` computes them with scikit-image and
flip-evaluator instead, the oracles the Dr.Jit versions are tested against.

Every function refuses what it cannot judge before computing anything, naming the image and what
it expected (study.metrics.checks): 8-bit figures take uint8 images, linear ones float images,
display images for FLIP lie in [0, 1], and NaN/Inf or mismatched shapes are refused.
"""
from __future__ import annotations

import math

import numpy as np

from study.metrics import checks
from study.metrics import flip as F
from study.metrics import ssim as S

METRICS = ("mse", "rmsd", "psnr", "snr", "ssim", "ssim_volume", "flip_ldr", "flip_hdr", "relmse_hdr")
HIGHER_IS_BETTER = {"psnr": True, "snr": True, "ssim": True, "ssim_volume": True, "jod": True}
IMPLS = ("drjit", "library")


def _impl(impl: str) -> str:
    if impl not in IMPLS:
        raise ValueError(f"metric implementation must be one of {IMPLS}, not {impl!r}")
    return impl


def better(metric: str, a: float, b: float) -> bool:
    """Whether figure `a` is strictly better than figure `b` of the same metric.

    Parameters
    ----------
    metric : str
        A name of `METRICS`, ``"temporal"`` or ``"jod"``: higher is better for PSNR, SNR, both
        SSIMs and JOD, lower for the others.
    a, b : float
        The two figures.

    Returns
    -------
    bool
    """
    return a > b if HIGHER_IS_BETTER.get(metric, False) else a < b


def _eight_bit(metric: str, ref8, x8) -> tuple[np.ndarray, np.ndarray]:
    ref8, x8 = checks.as_array(metric, "reference", ref8), checks.as_array(metric, "test image", x8)
    checks.same_shape(metric, ref8, x8)
    if ref8.dtype != np.uint8 or x8.dtype != np.uint8:
        raise ValueError(f"{metric}: uint8 8-bit display images expected, got {ref8.dtype} and {x8.dtype}")
    return ref8, x8


def mse(ref8: np.ndarray, x8: np.ndarray) -> float:
    """Mean squared error over all pixels and channels of two 8-bit images, in 8-bit units^2.

    Parameters
    ----------
    ref8, x8 : numpy.ndarray
        Reference and test image, uint8, of one shape.

    Returns
    -------
    float
        mean((ref8 - x8)^2), computed exactly in float64.

    Raises
    ------
    ValueError
        If the shapes differ (both named) or an image is not uint8.
    """
    ref8, x8 = _eight_bit("MSE", ref8, x8)
    d = ref8.astype(np.float64) - x8.astype(np.float64)
    return float(np.mean(d * d))


def psnr_from_mse(m: float) -> float:
    """PSNR of 8-bit images from their MSE: 10 log10(255^2 / MSE).

    Parameters
    ----------
    m : float
        The MSE in 8-bit units^2 (`mse`), finite and >= 0.

    Returns
    -------
    float
        PSNR in dB, +inf for an MSE of 0.

    Raises
    ------
    ValueError
        If `m` is negative, NaN or infinite.
    """
    if not (isinstance(m, (int, float, np.floating, np.integer)) and math.isfinite(m) and m >= 0):
        raise ValueError(f"PSNR: the MSE must be a finite number >= 0, got {m!r}")
    return math.inf if m == 0 else 10 * math.log10(255.0 ** 2 / m)


def snr(ref8: np.ndarray, x8: np.ndarray) -> float:
    """Signal-to-noise ratio of two 8-bit images, MATLAB psnr's second output.

    Parameters
    ----------
    ref8, x8 : numpy.ndarray
        Reference and test image, uint8, of one shape.

    Returns
    -------
    float
        10 log10(sum ref^2 / sum (ref - x)^2) in dB, +inf for identical images.

    Raises
    ------
    ValueError
        If the shapes differ (both named) or an image is not uint8.
    """
    ref8, x8 = _eight_bit("SNR", ref8, x8)
    r = ref8.astype(np.float64)
    noise = float(np.sum((r - x8.astype(np.float64)) ** 2))
    return math.inf if noise == 0 else 10 * math.log10(float(np.sum(r * r)) / noise)


def ssim(ref8: np.ndarray, x8: np.ndarray, impl: str = "drjit",
         data_range: float | None = None) -> tuple[float, np.ndarray]:
    """Per-channel mean SSIM and its map (study.metrics.ssim.ssim, or scikit-image's).

    Parameters
    ----------
    ref8, x8 : numpy.ndarray
        Reference and test image, H x W x 3 of one shape, at least 11 x 11: uint8 8-bit display
        images, or float images with `data_range`.
    impl : {'drjit', 'library'}
        'library': scikit-image 0.26.0 ``structural_similarity`` with the same options.
    data_range : float, optional
        The span of values the images can take: 255 for uint8 when omitted, required for float.

    Returns
    -------
    mean : float
        Mean SSIM (the 5-pixel border cropped).
    map : numpy.ndarray
        (H, W) float64, the per-channel SSIM maps averaged over channels.

    Raises
    ------
    ValueError
        If `impl` is unknown or the pair is one SSIM cannot judge (study.metrics.ssim.check_pair).

    References
    ----------
    Wang et al. 2004, "Image quality assessment: from error visibility to structural similarity".
    """
    if _impl(impl) == "library":
        from skimage.metrics import structural_similarity
        ref8, x8, L = S.check_pair(ref8, x8, data_range, S.skimage_radius())
        mean, smap = structural_similarity(ref8, x8, gaussian_weights=True, sigma=1.5,
                                           use_sample_covariance=False, data_range=L, channel_axis=-1,
                                           K1=0.01, K2=0.03, full=True)
        return float(mean), smap.mean(axis=-1)
    return S.ssim(ref8, x8, data_range=data_range)


def ssim_volume(ref8: np.ndarray, x8: np.ndarray, data_range: float | None = None) -> float:
    """MATLAB's SSIM of the two H x W x 3 arrays as volumes (the thesis's SSIM).

    Parameters
    ----------
    ref8, x8 : numpy.ndarray
        Reference and test image, H x W x 3 of one shape: uint8 8-bit display images, or float
        images with `data_range`.
    data_range : float, optional
        The span of values the images can take: 255 for uint8 when omitted, required for float.

    Returns
    -------
    float
        The volume SSIM (study.metrics.ssim.ssim_volume).

    Raises
    ------
    ValueError
        If the pair is one SSIM cannot judge (study.metrics.ssim.check_pair).

    References
    ----------
    Wang et al. 2004; MATLAB R2018 ``ssim``, as used in Oliveros 2018, Improved Sampling for
    Temporal Anti-Aliasing, Lund University.
    """
    return S.ssim_volume(ref8, x8, data_range=data_range)


def flip(ref: np.ndarray, x: np.ndarray, mode: str, impl: str = "drjit",
         memo: dict | None = None) -> tuple[float, np.ndarray]:
    """LDR-FLIP or HDR-FLIP (study.metrics.flip.flip, or flip-evaluator's).

    Parameters
    ----------
    ref, x : numpy.ndarray
        Reference and test image, H x W x 3 of one shape. 'LDR': sRGB display images, float in
        [0, 1] or uint8; 'HDR': linear float images, >= 0.
    mode : {'LDR', 'HDR'}
    impl : {'drjit', 'library'}
        'library': flip-evaluator 1.7's ``evaluate``.
    memo : dict, optional
        The reference's half of the work, kept by a caller judging several images against it
        (study.metrics.flip.flip; 'drjit' only).

    Returns
    -------
    mean : float
    map : numpy.ndarray
        (H, W) float32, the per-pixel error in [0, 1].

    Raises
    ------
    ValueError
        If `impl` is unknown or the pair is one FLIP cannot judge in `mode`
        (study.metrics.flip.check_pair).

    References
    ----------
    Andersson et al. 2020, "FLIP: A Difference Evaluator for Alternating Images" (LDR);
    Andersson et al. 2021, "Visualizing Errors in Rendered High Dynamic Range Images" (HDR).
    """
    if _impl(impl) == "library":
        import flip_evaluator
        ref, x = F.check_pair(ref, x, mode)
        emap, mean, _ = flip_evaluator.evaluate(np.ascontiguousarray(ref, np.float32),
                                                np.ascontiguousarray(x, np.float32), mode, applyMagma=False)
        return float(mean), np.asarray(emap, np.float32).reshape(ref.shape[:2])
    return F.flip(ref, x, mode, memo=memo)


def relmse(ref: np.ndarray, x: np.ndarray) -> float:
    """Relative MSE in linear HDR: mean((x - r)^2 / (r^2 + 0.01)).

    Parameters
    ----------
    ref, x : numpy.ndarray
        Linear reference and test image, float, of one shape.

    Returns
    -------
    float

    Raises
    ------
    ValueError
        If the shapes differ (both named), an image is not float, or holds NaN/Inf.

    Notes
    -----
    The 0.01 keeps near-black pixels from dominating; the figure is the relative MSE common in
    rendering, on images without an absolute scale (study.display's linear values).
    """
    ref, x = checks.as_array("relMSE", "reference", ref), checks.as_array("relMSE", "test image", x)
    checks.same_shape("relMSE", ref, x)
    for n, a in (("reference", ref), ("test image", x)):
        if a.dtype.kind != "f":
            raise ValueError(f"relMSE: the {n} is {a.dtype}; linear float images expected")
    r = ref.astype(np.float64)
    out = float(np.mean((x.astype(np.float64) - r) ** 2 / (r * r + 0.01)))
    if not math.isfinite(out):      # NaN/Inf in an input reach the mean: found without a pass of its own
        checks.finite_span("relMSE", "reference", ref)
        checks.finite_span("relMSE", "test image", x)
        raise ValueError(f"relMSE overflowed ({out}): the images' values are too large")
    return out

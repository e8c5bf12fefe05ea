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


def _linear(name: str, a) -> np.ndarray:
    a = checks.as_array("metrics", name, a)
    if a.dtype.kind != "f":
        raise ValueError(f"metrics: the {name} is {a.dtype}; a linear float image expected")
    checks.finite_span("metrics", name, a)
    return a


def _technique(x_lin, x_disp, x8) -> tuple:
    """The technique's images, checked once per frame (however many references judge them):
    linear float and finite (or None), display as LDR-FLIP takes it, 8-bit uint8; and the display
    image as given (its dtype is compared with the reference's)."""
    if x_lin is not None:
        x_lin = _linear("technique image", x_lin)
    given = checks.as_array("metrics", "technique display image", x_disp)
    x_disp = F.check_image("LDR", "technique display image", given)
    return x_lin, x_disp, checks.as_array("metrics", "technique 8-bit image", x8), given


def _reference(ref_lin, ref_disp, ref8, x: tuple, memo: dict | None) -> tuple:
    """A reference's images checked as the technique's, and all six of one H x W x 3 shape. Its
    values are checked once per memo: a memo belongs to one reference (study.metrics.flip.flip)."""
    images = [checks.as_array("metrics", n, a) for n, a in (("reference image", ref_lin),
              ("reference display image", ref_disp), ("reference 8-bit image", ref8))]
    x_lin, x_disp, x8, given = x
    checks.rgb("metrics", images[2], x8, ("reference 8-bit image", "technique 8-bit image"))
    for n, a in zip(("reference image", "reference display image", "technique image", "technique display image"),
                    (*images[:2], x_lin, x_disp)):
        if a is not None:
            checks.same_shape("metrics", a, x8, (n, "technique 8-bit image"))
    checks.same_kind("LDR-FLIP", images[1], given, F.LDR_EXPECTED)
    if memo is None or ("checked",) not in memo or images[1].dtype == np.uint8:
        images[0] = _linear("reference image", images[0])
        images[1] = F.check_image("LDR", "reference display image", images[1])
        if memo is not None:
            memo[("checked",)] = True
    return tuple(images)


def all_metrics(ref_lin: np.ndarray, ref_disp: np.ndarray, ref8: np.ndarray,
                x_lin: np.ndarray | None, x_disp: np.ndarray, x8: np.ndarray,
                impl: str = "drjit", want_maps: bool = True, memo: dict | None = None) -> tuple[dict, dict]:
    """Every metric of `METRICS` for one image, and its SSIM and FLIP maps.

    Parameters
    ----------
    ref_lin : numpy.ndarray
        The linear reference, H x W x 3 float (negative values are clipped to 0 for HDR-FLIP).
    ref_disp : numpy.ndarray
        Its display image: sRGB, float in [0, 1] (study.display).
    ref8 : numpy.ndarray
        Its 8-bit display image, uint8.
    x_lin : numpy.ndarray or None
        The technique's linear image, or None for a technique whose output is a display image
        (FXAA): its HDR figures are not defined and are reported as None.
    x_disp, x8 : numpy.ndarray
        The technique's display image (float in [0, 1]) and 8-bit display image (uint8).
    impl : {'drjit', 'library'}
        SSIM and FLIP in Dr.Jit, or with scikit-image and flip-evaluator (their oracles).
    want_maps : bool
        Return the maps (False: none kept; the scalars need them anyway).
    memo : dict, optional
        One dict per reference, for a caller judging several images against it (FLIP keeps the
        reference's half of its work there; study.metrics.flip.flip).

    Returns
    -------
    figures : dict
        metric -> value for every name of `METRICS` (None where not defined).
    maps : dict
        'ssim', 'flip_ldr' and (with `x_lin`) 'flip_hdr' -> (H, W) map; empty without `want_maps`.

    Raises
    ------
    ValueError
        If a linear or display image holds NaN/Inf (the image and the count named), or any
        metric refuses its pair (shapes, dtypes, ranges: `mse`, study.metrics.ssim.check_pair,
        study.metrics.flip.check_pair).

    References
    ----------
    Wang et al. 2004 (SSIM); Andersson et al. 2020 (FLIP) and 2021 (HDR-FLIP); the volume SSIM
    of Oliveros 2018, Improved Sampling for Temporal Anti-Aliasing, Lund University.
    """
    drjit = _impl(impl) == "drjit"
    x = _technique(x_lin, x_disp, x8)
    ref_lin, ref_disp, ref8 = _reference(ref_lin, ref_disp, ref8, x, memo)
    x_lin, x_disp, x8 = x[:3]
    m = mse(ref8, x8)
    if drjit:
        s, smap, s_vol = S.ssim_both(ref8, x8)
        fl, fmap = F._flip(ref_disp, x_disp, "LDR", None, memo, None)
    else:
        s, smap = ssim(ref8, x8, impl)
        s_vol = ssim_volume(ref8, x8)
        fl, fmap = flip(ref_disp, x_disp, "LDR", impl)
    out = {"mse": m, "rmsd": math.sqrt(m), "psnr": psnr_from_mse(m), "snr": snr(ref8, x8), "ssim": s,
           "ssim_volume": s_vol, "flip_ldr": fl, "flip_hdr": None, "relmse_hdr": None}
    maps = {"ssim": smap, "flip_ldr": fmap}
    if x_lin is not None:
        # clipped at 0 (HDR-FLIP's input); finite, checked above
        r0, x0 = np.maximum(ref_lin, 0), np.maximum(x_lin, 0)
        out["flip_hdr"], maps["flip_hdr"] = F._flip(r0, x0, "HDR", None, memo, None) if drjit else flip(r0, x0, "HDR", impl)
        out["relmse_hdr"] = relmse(ref_lin, x_lin)
    return out, (maps if want_maps else {})


def all_metrics_against(refs: list, x_lin: np.ndarray | None, x_disp: np.ndarray, x8: np.ndarray,
                        want_maps: list | None = None, hdr: bool = True) -> list:
    """`all_metrics` of one image against several references, its own half of SSIM and FLIP computed once.

    Parameters
    ----------
    refs : list of tuple
        (linear, display, 8-bit, memo) per reference (a reference and its two halves), each as
        `all_metrics`'s ref_lin, ref_disp, ref8 and memo.
    x_lin : numpy.ndarray or None
        The technique's linear image (None: a display-space technique).
    x_disp, x8 : numpy.ndarray
        Its display image (float in [0, 1]) and 8-bit display image (uint8).
    want_maps : list of bool, optional
        Whether to keep the maps, one flag per reference (default: all).
    hdr : bool
        False: no figure in linear HDR (FLIP HDR, relMSE: None), for a test that prints none.

    Returns
    -------
    list of tuple
        (figures, maps) per reference, the same values as `all_metrics` pair by pair (tested).

    Raises
    ------
    ValueError
        As `all_metrics`.

    References
    ----------
    As `all_metrics`.
    """
    x = _technique(x_lin, x_disp, x8)
    refs = [(*_reference(*r[:3], x, r[3]), r[3]) for r in refs]
    x_lin, x_disp, x8 = x[:3]
    want_maps = want_maps or [True] * len(refs)
    ssims = S.ssim_against([r[2] for r in refs], x8, [r[3] for r in refs])
    xmemo: dict = {}
    out = []
    for (ref_lin, ref_disp, ref8, memo), (s, smap, s_vol), keep in zip(refs, ssims, want_maps):
        m = mse(ref8, x8)
        fl, fmap = F._flip(ref_disp, x_disp, "LDR", None, memo, xmemo)
        figs = {"mse": m, "rmsd": math.sqrt(m), "psnr": psnr_from_mse(m), "snr": snr(ref8, x8), "ssim": s,
                "ssim_volume": s_vol, "flip_ldr": fl, "flip_hdr": None, "relmse_hdr": None}
        maps = {"ssim": smap, "flip_ldr": fmap}
        if x_lin is not None and hdr:
            figs["flip_hdr"], maps["flip_hdr"] = F._flip(np.maximum(ref_lin, 0), np.maximum(x_lin, 0), "HDR",
                                                         None, memo, xmemo)
            figs["relmse_hdr"] = relmse(ref_lin, x_lin)
        out.append((figs, maps if keep else {}))
    return out


class TemporalInstability:
    """RMS (8-bit units) of the error of frame-to-frame differences against the reference's.

    Flicker and ghost trails raise it, a stable sequence that follows the reference keeps it low.
    Fed one (reference, technique) pair of 8-bit frames at a time, in sequence order (`add`);
    `value` gives the figure.

    Attributes
    ----------
    frames : int
        Frames added so far.
    """

    def __init__(self):
        self.frames, self._acc, self._n, self._prev = 0, 0.0, 0, None

    def add(self, ref8: np.ndarray, x8: np.ndarray) -> None:
        """Add the next frame of the sequence.

        Parameters
        ----------
        ref8, x8 : numpy.ndarray
            The reference's and the technique's frame, uint8, of one shape (that of the frames
            added before).

        Raises
        ------
        ValueError
            If a frame is not uint8, the two differ in shape, or their shape is not the earlier
            frames'.
        """
        # in integers: 8-bit differences of differences (|d| <= 510) squared and summed exactly,
        # the same value as in float64 at a sixth of the time
        r, x = np.asarray(ref8), np.asarray(x8)
        if r.dtype != np.uint8 or x.dtype != np.uint8:
            raise ValueError(f"temporal instability: 8-bit frames expected, got {r.dtype} and {x.dtype}")
        checks.same_shape("temporal instability", r, x, ("reference frame", "technique frame"))
        if self._prev is not None and r.shape != self._prev[0].shape:
            raise ValueError(f"temporal instability: frame {self.frames} is {r.shape}, "
                             f"the earlier frames {self._prev[0].shape}")
        r, x = r.astype(np.int32), x.astype(np.int32)
        if self._prev is not None:
            d = (x - self._prev[1]) - (r - self._prev[0])
            self._acc += float(np.sum(d * d, dtype=np.int64))
            self._n += d.size
        self._prev = (r, x)
        self.frames += 1

    def value(self) -> float:
        """The figure: RMS of the differences' errors, in 8-bit units.

        Returns
        -------
        float
            NaN for fewer than two frames.
        """
        return math.sqrt(self._acc / self._n) if self._n else math.nan


def temporal_instability(ref_seq: list[np.ndarray], x_seq: list[np.ndarray]) -> float:
    """`TemporalInstability` of two whole sequences.

    Parameters
    ----------
    ref_seq, x_seq : list of numpy.ndarray
        The reference's and the technique's 8-bit frames (uint8, one shape), in sequence order.

    Returns
    -------
    float
        The RMS in 8-bit units; NaN for fewer than two frames.

    Raises
    ------
    ValueError
        If the sequences differ in length, or as `TemporalInstability.add`.
    """
    if len(ref_seq) != len(x_seq):
        raise ValueError(f"temporal instability: {len(ref_seq)} reference frames and {len(x_seq)} technique frames")
    acc = TemporalInstability()
    for r, x in zip(ref_seq, x_seq):
        acc.add(r, x)
    return acc.value()


def judge_run(images: dict, output_space: str, refs: dict, displays: dict, ref8: dict, kept: list[int],
              maps_for=None, impl: str = "drjit"):
    """Metrics of every kept frame of one technique's run, the sequence's temporal instability, and maps.

    The whole-sequence form (study.engine.judge judges a test's runs together, against the
    references' halves too); tested to agree with it.

    Parameters
    ----------
    images : dict
        frame -> the technique's H x W x 3 float image.
    output_space : {'linear', 'display'}
        The technique's output space (study.display.DisplayTransform.output).
    refs : dict
        frame -> reference (its ``image``, linear float).
    displays : dict
        frame -> study.display.DisplayTransform.
    ref8 : dict
        frame -> the reference's 8-bit display image (uint8).
    kept : list of int
        The frames judged, in sequence order.
    maps_for : iterable of int, optional
        Frames whose maps to return; None: the last kept frame's.
    impl : {'drjit', 'library'}

    Returns
    -------
    result : dict
        'per_frame' (frame as str -> figures of `all_metrics`) and 'temporal' (NaN for one frame).
    maps : dict
        The last kept frame's maps, or frame -> maps for the frames of `maps_for`.

    Raises
    ------
    ValueError
        As `all_metrics` and `TemporalInstability.add`.
    """
    per_frame, seq8, maps = {}, [], {}
    wanted = {kept[-1]} if maps_for is None else set(maps_for)
    for t in kept:
        disp = displays[t]
        x_lin, x_disp, x8 = disp.output(images[t], output_space)
        seq8.append(x8)
        per_frame[t], m = all_metrics(refs[t].image, disp.encode(refs[t].image), ref8[t], x_lin, x_disp, x8,
                                      impl=impl, want_maps=t in wanted)
        if t in wanted:
            maps[t] = m
    temporal = temporal_instability([ref8[t] for t in kept], seq8) if len(kept) > 1 else math.nan
    result = {"per_frame": {str(t): v for t, v in per_frame.items()}, "temporal": temporal}
    return result, (maps.get(kept[-1], {}) if maps_for is None else maps)

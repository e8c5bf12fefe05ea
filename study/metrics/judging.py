"""Every metric of study.metrics.suite for one frame against its reference (or several references,
each checked and half-computed once), and a technique's whole run judged frame by frame with its
temporal instability (study.metrics.temporal).
"""
from __future__ import annotations

import math

import numpy as np

from study.metrics import checks
from study.metrics import flip as F
from study.metrics import ssim as S
from study.metrics import ssim_against as SA
from study.metrics.suite import _impl, flip, mse, psnr_from_mse, relmse, snr, ssim, ssim_volume
from study.metrics.temporal import temporal_instability
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
    ssims = SA.ssim_against([r[2] for r in refs], x8, [r[3] for r in refs])
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

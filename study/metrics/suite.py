"""Image metrics (spec section 9): on 8-bit display images as the thesis did, plus FLIP and a
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
"""
from __future__ import annotations

import math

import numpy as np

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
    """True when a is strictly better than b for this metric."""
    return a > b if HIGHER_IS_BETTER.get(metric, False) else a < b


def mse(ref8: np.ndarray, x8: np.ndarray) -> float:
    d = ref8.astype(np.float64) - x8.astype(np.float64)
    return float(np.mean(d * d))


def psnr_from_mse(m: float) -> float:
    return math.inf if m == 0 else 10 * math.log10(255.0 ** 2 / m)


def snr(ref8: np.ndarray, x8: np.ndarray) -> float:
    r = ref8.astype(np.float64)
    noise = float(np.sum((r - x8.astype(np.float64)) ** 2))
    return math.inf if noise == 0 else 10 * math.log10(float(np.sum(r * r)) / noise)


def ssim(ref8: np.ndarray, x8: np.ndarray, impl: str = "drjit") -> tuple[float, np.ndarray]:
    """(mean SSIM, per-pixel SSIM map averaged over channels)."""
    if _impl(impl) == "library":
        from skimage.metrics import structural_similarity
        mean, smap = structural_similarity(ref8, x8, gaussian_weights=True, sigma=1.5,
                                           use_sample_covariance=False, data_range=255, channel_axis=-1,
                                           K1=0.01, K2=0.03, full=True)
        return float(mean), smap.mean(axis=-1)
    return S.ssim(ref8, x8)


def ssim_volume(ref8: np.ndarray, x8: np.ndarray) -> float:
    """MATLAB's SSIM of the two H x W x 3 arrays as volumes (the thesis's SSIM)."""
    return S.ssim_volume(ref8, x8)


def flip(ref: np.ndarray, x: np.ndarray, mode: str, impl: str = "drjit",
         memo: dict | None = None) -> tuple[float, np.ndarray]:
    if _impl(impl) == "library":
        import flip_evaluator
        emap, mean, _ = flip_evaluator.evaluate(np.ascontiguousarray(ref, np.float32),
                                                np.ascontiguousarray(x, np.float32), mode, applyMagma=False)
        return float(mean), np.asarray(emap, np.float32).reshape(ref.shape[:2])
    return F.flip(ref, x, mode, memo=memo)


def relmse(ref: np.ndarray, x: np.ndarray) -> float:
    r = ref.astype(np.float64)
    return float(np.mean((x.astype(np.float64) - r) ** 2 / (r * r + 0.01)))


def all_metrics(ref_lin: np.ndarray, ref_disp: np.ndarray, ref8: np.ndarray,
                x_lin: np.ndarray | None, x_disp: np.ndarray, x8: np.ndarray,
                impl: str = "drjit", want_maps: bool = True, memo: dict | None = None) -> tuple[dict, dict]:
    """Scalar metrics and maps for one image. `x_lin` is None for techniques whose output is a
    display image (FXAA): their HDR metrics are not defined and are reported as None.
    `want_maps=False` returns no maps (the scalars need them anyway; this only saves keeping them).
    `memo`: one dict per reference, for a caller judging several images against it (FLIP keeps the
    reference's half of its work there; study.metrics.flip.flip)."""
    for name, a in (("reference", ref_lin), ("technique", x_lin), ("technique display", x_disp)):
        if a is not None and not np.all(np.isfinite(a)):
            raise ValueError(f"{name} image holds {int(np.count_nonzero(~np.isfinite(a)))} NaN/Inf values")
    m = mse(ref8, x8)
    if _impl(impl) == "drjit":
            s, smap, s_vol = S.ssim_both(ref8, x8)
    else:
        s, smap = ssim(ref8, x8, impl)
        s_vol = ssim_volume(ref8, x8)
    fl, fmap = flip(ref_disp, x_disp, "LDR", impl, memo)
    out = {"mse": m, "rmsd": math.sqrt(m), "psnr": psnr_from_mse(m), "snr": snr(ref8, x8), "ssim": s,
           "ssim_volume": s_vol, "flip_ldr": fl, "flip_hdr": None, "relmse_hdr": None}
    maps = {"ssim": smap, "flip_ldr": fmap}
    if x_lin is not None:
        out["flip_hdr"], maps["flip_hdr"] = flip(np.maximum(ref_lin, 0), np.maximum(x_lin, 0), "HDR", impl, memo)
        out["relmse_hdr"] = relmse(ref_lin, x_lin)
    return out, (maps if want_maps else {})


def all_metrics_against(refs: list, x_lin: np.ndarray | None, x_disp: np.ndarray, x8: np.ndarray,
                        want_maps: list | None = None, hdr: bool = True) -> list:
    """all_metrics of one image against each reference of `refs` ((linear, display, 8-bit, memo)
    each: the reference and its two halves), the image's own half of SSIM and FLIP computed once
    for all of them. Same values as all_metrics (tested). `want_maps`: a flag per reference.
    `hdr=False`: no figure in linear HDR (FLIP HDR, relMSE: None), for a test that prints none."""
    for name, a in [("technique", x_lin), ("technique display", x_disp)] + [("reference", r[0]) for r in refs]:
        if a is not None and not np.all(np.isfinite(a)):
            raise ValueError(f"{name} image holds {int(np.count_nonzero(~np.isfinite(a)))} NaN/Inf values")
    want_maps = want_maps or [True] * len(refs)
    ssims = S.ssim_against([r[2] for r in refs], x8, [r[3] for r in refs])
    xmemo: dict = {}
    out = []
    for (ref_lin, ref_disp, ref8, memo), (s, smap, s_vol), keep in zip(refs, ssims, want_maps):
        m = mse(ref8, x8)
        fl, fmap = F.flip(ref_disp, x_disp, "LDR", memo=memo, xmemo=xmemo)
        figs = {"mse": m, "rmsd": math.sqrt(m), "psnr": psnr_from_mse(m), "snr": snr(ref8, x8), "ssim": s,
                "ssim_volume": s_vol, "flip_ldr": fl, "flip_hdr": None, "relmse_hdr": None}
        maps = {"ssim": smap, "flip_ldr": fmap}
        if x_lin is not None and hdr:
            figs["flip_hdr"], maps["flip_hdr"] = F.flip(np.maximum(ref_lin, 0), np.maximum(x_lin, 0), "HDR",
                                                        memo=memo, xmemo=xmemo)
            figs["relmse_hdr"] = relmse(ref_lin, x_lin)
        out.append((figs, maps if keep else {}))
    return out


class TemporalInstability:
    """RMS (8-bit units) of the error of frame-to-frame differences against the reference's:
    flicker and ghost trails raise it, a stable sequence that follows the reference keeps it low.
    Fed one (reference, technique) pair of 8-bit frames at a time, in sequence order."""

    def __init__(self):
        self.frames, self._acc, self._n, self._prev = 0, 0.0, 0, None

    def add(self, ref8: np.ndarray, x8: np.ndarray) -> None:
        # in integers: 8-bit differences of differences (|d| <= 510) squared and summed exactly,
        # the same value as in float64 at a sixth of the time
        r, x = np.asarray(ref8), np.asarray(x8)
        if r.dtype != np.uint8 or x.dtype != np.uint8:
            raise ValueError(f"temporal instability: 8-bit frames expected, got {r.dtype} and {x.dtype}")
        r, x = r.astype(np.int32), x.astype(np.int32)
        if self._prev is not None:
            d = (x - self._prev[1]) - (r - self._prev[0])
            self._acc += float(np.sum(d * d, dtype=np.int64))
            self._n += d.size
        self._prev = (r, x)
        self.frames += 1

    def value(self) -> float:
        return math.sqrt(self._acc / self._n) if self._n else math.nan


def temporal_instability(ref_seq: list[np.ndarray], x_seq: list[np.ndarray]) -> float:
    """TemporalInstability of whole sequences (NaN for fewer than two frames)."""
    acc = TemporalInstability()
    for r, x in zip(ref_seq, x_seq):
        acc.add(r, x)
    return acc.value()


def judge_run(images: dict, output_space: str, refs: dict, displays: dict, ref8: dict, kept: list[int],
              maps_for=None, impl: str = "drjit"):
    """Metrics of every kept frame of one technique's run against its references, the temporal
    instability of the sequence, and maps: those of the last kept frame (the default), or, when
    `maps_for` is given, a dict frame -> maps for the kept frames in it (a table or figure's)."""
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

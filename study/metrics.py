"""Image metrics (spec section 9): on 8-bit display images as the thesis did, plus FLIP and a
relative MSE in linear HDR so tone mapping cannot hide errors.

  MSE, RMSD        over all pixels and channels of the 8-bit images
  PSNR             10 log10(255^2 / MSE), +inf when MSE = 0
  SNR              10 log10(sum ref^2 / sum (ref - x)^2)  (MATLAB psnr's second output)
  SSIM             Wang et al.: Gaussian window sigma 1.5, K1 0.01, K2 0.03, population covariance,
                   data_range 255 (scikit-image, pinned: its border handling changed over versions)
  FLIP LDR / HDR   flip-evaluator, on the display images and on the linear ones
  relMSE (HDR)     mean((x - r)^2 / (r^2 + 0.01)) in linear HDR
"""
from __future__ import annotations

import math

import numpy as np
from skimage.metrics import structural_similarity

METRICS = ("mse", "rmsd", "psnr", "snr", "ssim", "flip_ldr", "flip_hdr", "relmse_hdr")
HIGHER_IS_BETTER = {"psnr": True, "snr": True, "ssim": True}


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


def ssim(ref8: np.ndarray, x8: np.ndarray) -> tuple[float, np.ndarray]:
    """(mean SSIM, per-pixel SSIM map averaged over channels)."""
    mean, smap = structural_similarity(ref8, x8, gaussian_weights=True, sigma=1.5,
                                       use_sample_covariance=False, data_range=255, channel_axis=-1,
                                       K1=0.01, K2=0.03, full=True)
    return float(mean), smap.mean(axis=-1)


def flip(ref: np.ndarray, x: np.ndarray, mode: str) -> tuple[float, np.ndarray]:
    import flip_evaluator
    emap, mean, _ = flip_evaluator.evaluate(np.ascontiguousarray(ref, np.float32),
                                            np.ascontiguousarray(x, np.float32), mode, applyMagma=False)
    return float(mean), np.asarray(emap, np.float32).reshape(ref.shape[:2])


def relmse(ref: np.ndarray, x: np.ndarray) -> float:
    r = ref.astype(np.float64)
    return float(np.mean((x.astype(np.float64) - r) ** 2 / (r * r + 0.01)))


def all_metrics(ref_lin: np.ndarray, ref_disp: np.ndarray, ref8: np.ndarray,
                x_lin: np.ndarray | None, x_disp: np.ndarray, x8: np.ndarray) -> tuple[dict, dict]:
    """Scalar metrics and maps for one image. `x_lin` is None for techniques whose output is a
    display image (FXAA): their HDR metrics are not defined and are reported as None."""
    for name, a in (("reference", ref_lin), ("technique", x_lin), ("technique display", x_disp)):
        if a is not None and not np.all(np.isfinite(a)):
            raise ValueError(f"{name} image holds {int(np.count_nonzero(~np.isfinite(a)))} NaN/Inf values")
    m = mse(ref8, x8)
    s, smap = ssim(ref8, x8)
    fl, fmap = flip(ref_disp, x_disp, "LDR")
    out = {"mse": m, "rmsd": math.sqrt(m), "psnr": psnr_from_mse(m), "snr": snr(ref8, x8), "ssim": s,
           "flip_ldr": fl, "flip_hdr": None, "relmse_hdr": None}
    maps = {"ssim": smap, "flip_ldr": fmap}
    if x_lin is not None:
        out["flip_hdr"], maps["flip_hdr"] = flip(np.maximum(ref_lin, 0), np.maximum(x_lin, 0), "HDR")
        out["relmse_hdr"] = relmse(ref_lin, x_lin)
    return out, maps


def temporal_instability(ref_seq: list[np.ndarray], x_seq: list[np.ndarray]) -> float:
    """RMS (8-bit units) of the error of frame-to-frame differences against the reference's:
    flicker and ghost trails raise it, a stable sequence that follows the reference keeps it low."""
    if len(ref_seq) < 2:
        return math.nan
    acc, n = 0.0, 0
    for k in range(1, len(ref_seq)):
        dr_ = ref_seq[k].astype(np.float64) - ref_seq[k - 1]
        dx = x_seq[k].astype(np.float64) - x_seq[k - 1]
        acc += float(np.sum((dx - dr_) ** 2))
        n += dr_.size
    return math.sqrt(acc / n)


def judge_run(images: dict, output_space: str, refs: dict, displays: dict, ref8: dict, kept: list[int]):
    """Metrics of every kept frame of one technique's run against its references, the temporal
    instability of the sequence, and the maps of the last frame."""
    per_frame, seq8, maps = {}, [], {}
    for t in kept:
        x, disp = images[t], displays[t]
        if output_space == "display":
            x_lin, x_disp = None, np.clip(x.astype(np.float64), 0, 1)
        else:
            x_lin, x_disp = x, disp.encode(x)
        x8 = np.round(x_disp * 255).astype(np.uint8)
        seq8.append(x8)
        per_frame[t], maps = all_metrics(refs[t].image, disp.encode(refs[t].image), ref8[t], x_lin, x_disp, x8)
    temporal = temporal_instability([ref8[t] for t in kept], seq8) if len(kept) > 1 else math.nan
    return {"per_frame": {str(t): v for t, v in per_frame.items()}, "temporal": temporal}, maps

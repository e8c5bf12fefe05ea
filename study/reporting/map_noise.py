"""Where a shown SSIM/FLIP map cannot be read: the pixels whose reference is too noisy for the map's
colour scale.

A map (SSIM per pixel, or FLIP LDR per pixel) is computed against the test's own reference,
the mean of finitely many path-traced samples; its per-pixel standard error in the display domain
(references.result.Reference.stderr through the display transform, references.estimates.display_se)
moves the map too. The tables' jackknife (study.metrics.uncertainty) corrects the figures, not the
pixels, so the maps mark the pixels where that noise exceeds what the map's colour scale resolves:

    the rule   a map over [0, 1] is read in MAP_STEPS colour steps, so it resolves 1 / MAP_STEPS; the
               map's threshold D (8-bit LSB) is the smallest reference SE that moves it by that step:
               the RMS change of the map when a flat grey reference gets Gaussian noise of SE D
               (the technique's image the clean field), at the most sensitive of GREYS, with the
               noise the same in the three channels or independent in each, whichever moves it more.
               A pixel is marked where the reference's display SE (its worst channel) exceeds D.

D is measured with the metrics' library implementations (scikit-image's SSIM on unquantised values,
flip-evaluator's FLIP LDR), the oracles the study's own are tested against. Marked pixels are
painted MARK_RGB, a colour neither the grey SSIM map nor magma uses: no value is shown where none is
resolved. The alternative, refining the shown frames' references until no pixel is marked, costs
render time; marking keeps the study's run time.
"""
from __future__ import annotations

import math

import numpy as np

MAP_STEPS = 32          # about the steps of 3 L* that a viewer tells apart over the map's 0-100 L* range
MARK_RGB = (0, 229, 255)
GREYS = (0.02, 0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 0.95)
KINDS = ("ssim", "flip")
_SIDE = 40              # the calibration field, pixels
_MARGIN = 8             # its border, left out of the RMS (SSIM's and FLIP's filters reach past it)


def _map(kind: str, ref: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The map of kind `kind` (its shown value, in [0, 1]) of display images ref and x in [0, 1]."""
    if kind == "ssim":
        from skimage.metrics import structural_similarity
        _, smap = structural_similarity(ref * 255.0, x * 255.0, gaussian_weights=True, sigma=1.5,
                                        use_sample_covariance=False, data_range=255, channel_axis=-1,
                                        K1=0.01, K2=0.03, full=True)
        return np.clip(smap.mean(axis=-1), 0, 1)
    import flip_evaluator
    emap, _, _ = flip_evaluator.evaluate(np.ascontiguousarray(ref, np.float32), np.ascontiguousarray(x, np.float32),
                                         "LDR", applyMagma=False)
    return np.asarray(emap, np.float64).reshape(ref.shape[:2])


def _moves(kind: str, grey: float, se_lsb: float, z: np.ndarray) -> float:
    """RMS change of the map over the field's interior when the reference gets noise se_lsb * z."""
    clean = np.full(z.shape, grey)
    noisy = np.clip(clean + se_lsb / 255.0 * z, 0.0, 1.0)
    d = _map(kind, noisy, clean) - _map(kind, clean, clean)
    m = _MARGIN
    return float(np.sqrt(np.mean(d[m:-m, m:-m] ** 2)))


def noise_fields() -> dict:
    """The calibration's noise (fixed seed): 'shared' the same in the three channels, 'own' independent."""
    rng = np.random.default_rng(0)
    shared = np.repeat(rng.standard_normal((_SIDE, _SIDE, 1)), 3, axis=-1)
    return {"shared": shared, "own": rng.standard_normal((_SIDE, _SIDE, 3))}


def calibrate(kind: str) -> tuple[float, float, str]:
    """(D, grey, noise) of the map `kind` by the module's rule: the smallest reference SE (8-bit LSB,
    to 1e-3) that moves it by one of its MAP_STEPS colour steps, and the flat grey and noise where it
    does. Slow (FLIP: ~30 s); its result is THRESHOLDS, which tests/test_map_noise.py checks."""
    if kind not in KINDS:
        raise ValueError(f"map kind must be one of {KINDS}, not {kind!r}")
    step = 1.0 / MAP_STEPS
    best = (64.0, None, None)
    for grey in GREYS:
        for name, z in noise_fields().items():
            if _moves(kind, grey, best[0], z) < step:
                continue             # less sensitive here than where one was already found
            lo, hi = 0.0, best[0]    # the move grows with the noise: bisect for where it reaches a step
            while hi - lo > 5e-4:
                mid = (lo + hi) / 2
                lo, hi = (lo, mid) if _moves(kind, grey, mid, z) >= step else (mid, hi)
            best = (math.ceil(hi * 1000) / 1000, grey, name)     # up: it still reaches the step
    return best


# calibrate()'s results: map kind -> (D in LSB, the grey and the noise where the map is most sensitive)
THRESHOLDS = {"ssim": (1.370, 0.02, "own"), "flip": (1.794, 0.95, "own")}


def threshold_lsb(kind: str) -> float:
    """D of the map `kind` ('ssim' or 'flip'): the reference SE (8-bit LSB) that moves it by one of its
    MAP_STEPS colour steps where it is most sensitive (the module's rule; THRESHOLDS)."""
    if kind not in KINDS:
        raise ValueError(f"map kind must be one of {KINDS}, not {kind!r}")
    return THRESHOLDS[kind][0]


def reference_se_lsb(ref, disp) -> np.ndarray:
    """(H, W) the reference's per-pixel standard error in the display domain of the transform `disp`
    (display.DisplayTransform) the maps were judged under, worst channel, in 8-bit LSB."""
    from references.estimates import display_se
    mean = np.asarray(ref.image, np.float64).reshape(-1, 3)
    se = np.asarray(ref.stderr, np.float64).reshape(-1, 3)
    cov = np.zeros((len(mean), 3, 3))
    cov[:, [0, 1, 2], [0, 1, 2]] = se * se
    return (display_se(disp, mean, cov).max(axis=-1) * 255.0).reshape(ref.image.shape[:2])


def marks(se_lsb: np.ndarray, kind: str) -> np.ndarray:
    """(H, W) bool: the pixels of a `kind` map whose reference SE (LSB) exceeds its threshold."""
    se = np.asarray(se_lsb, np.float64)
    if se.ndim != 2 or not np.all(np.isfinite(se)):
        raise ValueError(f"map marks: the reference SE must be a finite H x W array, got shape {se.shape}")
    return se > threshold_lsb(kind)


def paint(rgb8: np.ndarray, marked: np.ndarray) -> np.ndarray:
    """The 8-bit map (H x W grey or H x W x 3) as RGB with the marked pixels painted MARK_RGB."""
    a = np.asarray(rgb8, np.uint8)
    out = np.repeat(a[..., None], 3, axis=-1) if a.ndim == 2 else a.copy()
    out[marked] = MARK_RGB
    return out


def note(counts: dict, size: int) -> str:
    """The maps' caption: the rule and how many of `size` pixels each kind of map marks."""
    parts = [f"{k.upper() if k == 'ssim' else 'FLIP'} {counts[k]} (reference SE > {threshold_lsb(k):.3g} LSB)"
             for k in KINDS if k in counts]
    return (f"Maps: pixels painted cyan are not resolved, the reference's own noise there (its display-domain SE) "
            f"could move the map by more than one of its {MAP_STEPS} colour steps (study.reporting.map_noise); "
            f"marked, not refined: " + ", ".join(parts) + f" of {size} pixels.")


__all__ = ["MAP_STEPS", "MARK_RGB", "THRESHOLDS", "calibrate", "threshold_lsb", "reference_se_lsb", "marks", "paint", "note"]

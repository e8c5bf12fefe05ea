"""How much a reference's own noise moves a figure, from the reference's two independent halves.

A reference is the mean of M samples per pixel; its halves A and B (references.render: half of
every pixel's samples each, so each has twice the mean's variance) are independent estimates of
the same image. For any metric f judged against a reference with noise of variance v, to first
order in the noise
    f(ref) = f0 + g.e + c v       (g.e: a random term of mean 0; c v: a bias, e.g. + mean(sigma^2) for MSE)
so f(A) and f(B) carry twice the bias, and
    f0 ~ 2 f(ref) - (f(A) + f(B)) / 2          the jackknife: the bias removed
    |f(A) - f(B)| ~ 2 sd(g.e)                   the random part left, as about two standard deviations.
Nothing here assumes what f is: every figure (MSE, PSNR, SNR, SSIM, volume SSIM, FLIP LDR/HDR,
relMSE, the temporal RMS) is computed in full against all three images, 8-bit quantisation of
the display images included, so the estimate covers it. MSE-derived figures (RMSD, PSNR) are
derived from the corrected MSE rather than corrected on their own, so they stay consistent; so is
SNR (PSNR with the reference's mean power for the peak).

A figure that is a mean over frames (each frame against its own, independent reference) keeps
the mean of the corrected values, and its uncertainty is the per-frame ones added in quadrature
over n (`pooled`); one frame's is a single draw of |f(A) - f(B)|, about 2 sd on average but with
a spread of its own, which is why a study refines to a tolerance with a margin (study.engine.precision).

References
----------
B. Efron, C. Stein, "The Jackknife Estimate of Variance", The Annals of Statistics 9(3), 1981;
M. H. Quenouille, "Notes on Bias in Estimation", Biometrika 43(3/4), 1956 (the bias correction).
"""
from __future__ import annotations

import math

# Each figure's tolerance key: the tolerance that bounds its uncertainty (study.config.defaults).
TOLERANCE_OF = {"psnr": "psnr_db", "snr": "psnr_db", "ssim": "ssim", "ssim_volume": "ssim", "flip_ldr": "flip",
                "flip_hdr": "flip", "mse": "relative", "rmsd": "relative", "relmse_hdr": "relmse",
                "temporal": "relative"}
_DERIVED = ("rmsd", "psnr", "snr")
MEAN = "_mean"      # a metric's mean over a sequence's frames is the figure metric + MEAN ("mse_mean")


def _finite(*xs) -> bool:
    return all(x is not None and math.isfinite(x) for x in xs)


def jackknife(full: dict, a: dict, b: dict) -> tuple[dict, dict]:
    """One frame's figures with the reference's noise bias removed, and the uncertainty left.

    Parameters
    ----------
    full : dict
        metric -> figure judged against the reference (`study.metrics.judging.all_metrics`).
    a, b : dict
        The same judged against the reference's independent halves A and B.

    Returns
    -------
    corrected : dict
        metric -> 2 f(ref) - (f(A) + f(B)) / 2; RMSD, PSNR and SNR derived from the corrected
        MSE (clamped at 0). A figure that is None stays None; one that is infinite against any of
        the three (an exact match) is kept as judged.
    uncertainty : dict
        metric -> |f(A) - f(B)|, about two standard deviations of the random part (0 for an
        exact match, None where the figure is None).
    """
    out, u = {}, {}
    for k, f in full.items():
        fa, fb = a.get(k), b.get(k)
        if k in _DERIVED:
            continue
        if f is None or fa is None or fb is None:
            out[k], u[k] = f, None
        elif not _finite(f, fa, fb):
            out[k], u[k] = f, 0.0
        else:
            out[k], u[k] = 2 * f - (fa + fb) / 2, abs(fa - fb)
    if out.get("mse") is not None:
        m = max(out["mse"], 0.0)              # an unbiased estimate can fall below 0; MSE cannot
        out["mse"] = m
        out["rmsd"], u["rmsd"] = math.sqrt(m), (u["mse"] / (2 * math.sqrt(m)) if m > 0 else 0.0)
        out["psnr"] = math.inf if m == 0 else 10 * math.log10(255.0 ** 2 / m)
        u["psnr"] = 0.0 if m == 0 else 10 / math.log(10) * u["mse"] / m
        if "snr" in full:
            # SNR is PSNR with the reference's mean power for the peak: the same corrected MSE. Judged
            # on its own, the jackknife's bias removal in dB is not the MSE's (at 8 LSB SSAA 16x's
            # SNR on pipe moved 0.27 dB to the 0.5-LSB figure while its PSNR moved 0.04).
            snr, m0 = full["snr"], full["mse"]
            if snr is None or m0 is None or not _finite(snr) or m0 <= 0:
                out["snr"], u["snr"] = snr, (None if snr is None else 0.0)
            else:
                out["snr"] = math.inf if m == 0 else snr + 10 * math.log10(m0 / m)
                u["snr"] = u["psnr"]
    return out, u


def pooled(us: list) -> float | None:
    """The uncertainty of a mean over frames of figures with independent uncertainties.

    Parameters
    ----------
    us : list of float
        Each frame's uncertainty.

    Returns
    -------
    float or None
        sqrt(sum u^2) / n; None for no frames or where any frame's is None.
    """
    if not us or any(x is None for x in us):
        return None
    return math.sqrt(sum(x * x for x in us)) / len(us)


def tolerance(metric: str, value: float | None, tolerances: dict) -> float | None:
    """The absolute tolerance on a figure.

    Parameters
    ----------
    metric : str
        The figure's metric (a key of `TOLERANCE_OF`).
    value : float or None
        The figure.
    tolerances : dict
        Tolerance key -> tolerance (study.config.defaults): 'relative' (MSE, RMSD, temporal RMS)
        and 'relmse' as a fraction of the value, the others absolute (dB for PSNR and SNR).

    Returns
    -------
    float or None
        None for a metric without a tolerance, or a relative one on a missing or infinite value.
    """
    key = TOLERANCE_OF.get(metric.removesuffix(MEAN))     # a mean over frames: its metric's
    if key is None or key not in tolerances:
        return None
    if key in ("relative", "relmse"):
        return None if value is None or not math.isfinite(value) else tolerances[key] * abs(value)
    return tolerances[key]


def excess(metric: str, value: float | None, u: float | None, tolerances: dict) -> float | None:
    """The tolerance a figure's uncertainty exceeds.

    Parameters
    ----------
    metric : str
        The figure's metric.
    value : float or None
        The figure.
    u : float or None
        Its uncertainty (`jackknife`, `pooled`).
    tolerances : dict
        As `tolerance`.

    Returns
    -------
    float or None
        The tolerance, or None when `u` is within it (or either is None).
    """
    tol = tolerance(metric, value, tolerances)
    return tol if u is not None and tol is not None and u > tol else None


def over_tolerance(figures: dict, us: dict, tolerances: dict) -> dict:
    """The figures whose uncertainty exceeds their tolerance, and by how much.

    Parameters
    ----------
    figures : dict
        metric -> figure.
    us : dict
        metric -> its uncertainty.
    tolerances : dict
        As `tolerance`.

    Returns
    -------
    dict
        metric -> u / tolerance (> 1; inf for a tolerance of 0), only for those over it.
    """
    out = {}
    for k, u in us.items():
        tol = excess(k, figures.get(k), u, tolerances)
        if tol is not None:
            out[k] = u / tol if tol > 0 else math.inf
    return out


def decimals(metric: str, u: float | None, most: int) -> int:
    """The decimals a figure with uncertainty `u` supports: to u's first significant digit.

    Parameters
    ----------
    metric : str
        The figure's metric (every metric follows the same rule).
    u : float or None
        The uncertainty.
    most : int
        The table layout's decimals, the most returned.

    Returns
    -------
    int
        floor(-log10 u) within [0, most]; `most` where u is None, 0, negative or not finite.
    """
    if u is None or not math.isfinite(u) or u <= 0:
        return most
    return max(0, min(most, math.floor(-math.log10(u))))

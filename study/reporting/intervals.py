"""Confidence intervals of paired differences (the A/B comparison's and the findings')."""
from __future__ import annotations

import numpy as np


def bootstrap_ci(diffs: np.ndarray, n: int = 2000, seed: int = 0) -> tuple[float, float] | None:
    """95 % percentile-bootstrap interval of the mean (scipy.stats.bootstrap, `n` resamples, fixed
    seed); None for fewer than two values. Percentile, not BCa: BCa is undefined when every
    difference is equal (a technique against itself), which an A/B of identical code gives."""
    from scipy import stats          # its import is most of a second; only intervals need it
    diffs = np.asarray(diffs, np.float64)
    if len(diffs) < 2:
        return None
    if np.all(diffs == diffs[0]):
        return float(diffs[0]), float(diffs[0])
    res = stats.bootstrap((diffs,), np.mean, n_resamples=n, confidence_level=0.95, method="percentile",
                          random_state=np.random.default_rng(seed))
    return float(res.confidence_interval.low), float(res.confidence_interval.high)

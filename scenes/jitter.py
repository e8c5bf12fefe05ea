"""Sub-pixel jitter: the Halton(2, 3) sequence, as used by the thesis and most engines.

Frame k uses Halton index (k mod N) + 1: index 0 is skipped because it is (0, 0), which would sit
on the corner of the sampling square and repeat the pixel's corner every N frames. Each point u in
[0, 1)^2 becomes an offset u - 0.5 in pixels from the pixel centre, so offsets lie in [-0.5, 0.5)^2.
"""
from __future__ import annotations

import numpy as np

TAA_PERIOD = 16  # N for TAA; the accumulation buffer uses up to 128 or more


def radical_inverse(i: int, base: int) -> float:
    f, r = 1.0, 0.0
    while i > 0:
        f /= base
        r += f * (i % base)
        i //= base
    return r


def halton_offset(k: int, period: int = TAA_PERIOD) -> tuple[float, float]:
    """Offset in pixels of frame k's sample from the pixel centre."""
    if period < 1:
        raise ValueError(f"jitter period must be >= 1, got {period}")
    i = k % period + 1
    return radical_inverse(i, 2) - 0.5, radical_inverse(i, 3) - 0.5


def halton_offsets(n: int, period: int | None = None) -> np.ndarray:
    period = n if period is None else period
    return np.array([halton_offset(k, period) for k in range(n)])

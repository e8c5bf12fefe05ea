"""AA techniques, vectorised with Dr.Jit. `make(name, **overrides)` builds one by registry name.

Every technique: `needs` (buffers read), `params` (frozen, hashable), `reset()`,
`process(frame, *, jitter, far, reset=False) -> (H, W, 3) float32`.
"""
from __future__ import annotations

from typing import Callable

from .base import FEEDBACK_PRESETS, SHARPEN_KERNELS, TAAParams, Technique
from .baseline import BaselineTAA
from .improved import ImprovedParams, ImprovedTAA

TECHNIQUES: dict[str, Callable[..., Technique]] = {
    BaselineTAA.name: BaselineTAA,
    ImprovedTAA.name: ImprovedTAA,
}


def make(name: str, **overrides) -> Technique:
    """A fresh technique; overrides are parameter fields or `feedback='thesis'|'inside'`."""
    try:
        factory = TECHNIQUES[name]
    except KeyError:
        raise KeyError(f"unknown technique {name!r}; known: {sorted(TECHNIQUES)}") from None
    return factory(**overrides)


__all__ = ["TECHNIQUES", "make", "Technique", "TAAParams", "ImprovedParams", "BaselineTAA",
           "ImprovedTAA", "FEEDBACK_PRESETS", "SHARPEN_KERNELS"]

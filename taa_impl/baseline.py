"""Baseline TAA: Uncharted 4 (Xu 2016) / INSIDE (Pedersen 2016) as the thesis used it (spec §5).

Sharpening is applied to the displayed output only; the history keeps the unsharpened blend (Xu runs
the sharpen as a separate pass after TAA, INSIDE's history is the plain blend). Sharpening the
history would compound the kernel every frame (with Xu's 5/-1 kernel it diverges).

The current colour c is the raster's jittered sample as is (the spec's "un-jittered sample": we do
not resample it; jitter only moves where the sample was taken).
"""
from __future__ import annotations

import numpy as np

import backend  # noqa: F401
from backend import dr, mi

from . import kernels as K
from .base import TAAParams, Technique, from_drjit_color, from_drjit_scalar, sharpen_weight


def resolve(params: TAAParams, grid: K.Grid, c, history, velocity, bmin, bmax):
    """Steps 2, 4, 5: reproject, clip toward the box centre, blend with luminance feedback.

    No history (first frame, reset) or an off-screen reprojection gives c for that pixel."""
    if history is None:
        return c, None
    h, valid = K.reproject(grid, history, velocity)
    h = K.clip_toward_centre(h, bmin, bmax, params.clip_eps)
    k = K.feedback_weight(K.luminance(c, params.feedback_luma), K.luminance(h, params.feedback_luma),
                          params.k_min, params.k_max, params.feedback_floor)
    return dr.select(valid, K.lerp(c, h, k), c), valid


class TAATechnique(Technique):
    """Shared plumbing of the TAAs: colour history, a cached pixel grid, debug terms."""

    def _clear_history(self) -> None:
        self._history = None  # mi.Color3f: last unsharpened blend
        self._grid = None
        self._terms: dict = {}

    def _grid_for(self, w: int, h: int) -> K.Grid:
        if self._grid is None or (self._grid.w, self._grid.h) != (w, h):
            self._grid = K.Grid(w, h)
        return self._grid

    def debug_terms(self) -> dict[str, np.ndarray]:
        """Intermediate images of the last frame as NumPy (H, W[, C]) float32 arrays."""
        if not self._terms:
            return {}
        h, w = self._shape
        dr.eval(*self._terms.values())
        out = {}
        for key, v in self._terms.items():
            if isinstance(v, mi.Color3f):
                out[key] = from_drjit_color(v, h, w)
            elif isinstance(v, mi.Vector2f):
                out[key] = np.asarray(dr.ravel(v), np.float32).reshape(h, w, 2).copy()
            else:
                out[key] = from_drjit_scalar(mi.Float(v), h, w)
        return out

    @property
    def history(self) -> np.ndarray | None:
        """The stored (unsharpened) colour history as NumPy, or None after a reset."""
        if self._history is None:
            return None
        return from_drjit_color(self._history, *self._shape)


class BaselineTAA(TAATechnique):
    name = "taa_baseline"
    needs = frozenset({"color", "depth", "motion"})
    Params = TAAParams

    def _step(self, b: dict, w: int, h: int, far: float):
        p = self.params
        grid = self._grid_for(w, h)
        c = b["color"]
        velocity = K.closest_velocity(grid, b["depth"], b["motion"])
        bmin, bmax, bavg = K.neighbourhood(grid, c).averaged()
        blend, valid = resolve(p, grid, c, self._history, velocity, bmin, bmax)
        dr.eval(blend)
        self._history = blend
        self._terms = {"velocity": velocity, "box_min": bmin, "box_max": bmax, "box_avg": bavg,
                       "history_valid": mi.Float(dr.select(valid, 1.0, 0.0)) if valid is not None
                       else dr.zeros(mi.Float, grid.n),
                       "blend": blend}
        return K.sharpen(grid, blend, sharpen_weight(p.sharpen))

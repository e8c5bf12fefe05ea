"""TAA with sparse supersampling of the pixels whose history cannot be reused (Li, Chen, Zhang 2021,
Temporal anti-aliasing with sparse supersampling).

The paper's pipeline (its §1.1): the TAA pass also runs a "reuse validity test" per pixel and writes
a segmentation mask; pixels that fail are re-rendered with spatial supersampling (meshes, triangles
and fragments whose pixels all passed are culled); a final pass composites the TAA result and the
supersampled result by the mask. The paper compares against 8x SSAA and tunes the test's threshold
mu (smaller: better and slower), settling on mu = 0.2.

The test (paper eq. 1, whose formula was lost in the scrape; the text says: C is the pixel's current
colour, C_h the reprojected history colour, mu a constant threshold; "if the inequality holds the
reuse succeeds") is implemented as  D(c, h) <= mu  with a selectable distance D (`difference`):

  'tonemapped_max' (default)  max over R, G, B of |T(c) - T(h)|,  T(x) = max(x, 0) / (1 + max(x, 0))
  'linear_max'                max over R, G, B of |c - h| on the linear values
  'luma_relative'             |l_c - l_h| / max(l_c, l_h, luma_floor), Rec.709 luminance

Why the default: the paper's mu = 0.2 is a difference between colours of an 8-bit-style [0, 1]
framebuffer. Our colours are linear HDR, where a linear difference is unbounded (a 3 % flicker of a
value of 10 would fail, a black-to-grey change of 0.15 would pass). T is the per-channel Reinhard
curve: it maps HDR into [0, 1), has slope 1 at 0 (dark and mid values differ about as they would on
a [0, 1] scale) and compresses highlights, so mu keeps the meaning "a fifth of the displayable range"
at every exposure. The maximum over channels (rather than a luminance) catches changes of hue at equal
brightness (red to green), which are exactly the disocclusions and shading changes the paper targets;
it is the L-infinity form of |C - C_h| <= mu, the most conservative reading of the lost formula.

h is the history fetched at the reprojected position *before* the neighbourhood clip (the clip would
pull it into the box of current colours and hide the change the test is looking for). Pixels without
a usable history -- first frame, after a reset or a resolution change, reprojection off-screen, or
rejected by the reject_depth / reject_id switches -- are invalid too (the paper's reason (1),
"visibility changed", at its most certain).

Per frame: the baseline TAA runs everywhere unchanged (BaselineTAA._step, with all TAAParams switches);
its hook `_composite` makes out = supersampled where invalid, the TAA blend elsewhere;
that composite is the new history (so a re-rendered pixel restarts its history from an N-sample
estimate) and is sharpened for display exactly as the baseline's blend is.

Driver protocol (its contract's `extra_samples = params.samples`; study.engine.drive drives it):
  mask = tech.invalid_mask(frame)                  # (H, W) bool, no state change
  supersampled = <mean of params.samples jittered samples, rendered where mask is set, 0 elsewhere>
  out = tech.process(dataclasses.replace(frame, supersampled=supersampled, mask=mask))
  tech.last_stats -> {"invalid_fraction", "extra_samples", "pixels"}
`mask` may be a superset of the technique's own invalid pixels (what the driver rendered); a mask
that misses one of them, or supersampled=None, is an error. Without `mask`, process uses its own.
With mu = inf only pixels without history are invalid, and where the supersampled colour equals the
frame's colour the result is the baseline TAA's, bit for bit (tested).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

import backend  # noqa: F401
from backend import array, dr, mi

from . import kernels as K
from .base import TAAParams, from_drjit_color, to_drjit
from .contract import Frame, Inputs, as_frame, checked
from .baseline import BaselineTAA, fetch_history

DIFFERENCES = ("tonemapped_max", "linear_max", "luma_relative")


@dataclass(frozen=True)
class SparseParams(TAAParams):
    """Baseline TAA parameters plus the reuse test and the supersampling rate."""
    mu: float = 0.2                      # the paper's threshold; inf = only history-less pixels
    samples: int = 8                     # N of the supersampled colour (the paper's 8x SSAA)
    difference: str = "tonemapped_max"   # one of DIFFERENCES (module docstring)
    luma_floor: float = 0.2              # denominator floor of 'luma_relative'

    def __post_init__(self):
        super().__post_init__()
        mu = float(self.mu)
        if math.isnan(mu) or mu < 0:
            raise ValueError(f"mu must be >= 0 (inf allowed), got {self.mu!r}")
        object.__setattr__(self, "mu", mu)
        if isinstance(self.samples, bool) or int(self.samples) != self.samples or self.samples < 1:
            raise ValueError(f"samples must be an integer >= 1, got {self.samples!r}")
        object.__setattr__(self, "samples", int(self.samples))
        if self.difference not in DIFFERENCES:
            raise ValueError(f"difference must be one of {DIFFERENCES}, got {self.difference!r}")
        if not self.luma_floor > 0:
            raise ValueError("luma_floor must be > 0")


def _tonemap(c):
    x = dr.maximum(c, 0.0)
    return x / (1.0 + x)


def colour_difference(kind: str, c, h, luma_floor: float = 0.2):
    """D(c, h) per pixel (mi.Float) for the reuse test D <= mu (module docstring)."""
    if kind == "luma_relative":
        lc, lh = K.luminance(c, K.REC709), K.luminance(h, K.REC709)
        return dr.abs(lc - lh) / dr.maximum(dr.maximum(lc, lh), luma_floor)
    a = dr.abs(_tonemap(c) - _tonemap(h)) if kind == "tonemapped_max" else dr.abs(c - h)
    return dr.maximum(dr.maximum(a.x, a.y), a.z)


class SparseTAA(BaselineTAA):
    name = "taa_sparse"
    Params = SparseParams

    @classmethod
    def inputs_for(cls, params=None) -> Inputs:
        p = params if params is not None else cls.Params()
        return dataclasses.replace(super().inputs_for(p), extra_samples=p.samples)

    # -- the reuse test --------------------------------------------------------------------------
    def _invalid(self, grid: K.Grid, b: dict, velocity, reject):
        """True where the history cannot be reused (mi.Bool), evaluated."""
        p = self.params
        if self._history is None:
            return dr.full(mi.Bool, True, grid.n)
        h, valid = fetch_history(p, grid, self._history, velocity)   # not clipped
        if reject is not None:
            valid = valid & ~reject
        invalid = ~valid
        if math.isfinite(p.mu):
            invalid |= ~(colour_difference(p.difference, b["color"], h, p.luma_floor) <= p.mu)
        dr.eval(invalid)
        return invalid

    def invalid_mask(self, frame: Frame | dict | None = None, /, **fields) -> np.ndarray:
        """(H, W) bool: pixels of this frame that will need the supersampled colour, computed from
        the frame and the current history without changing any state. All True on the first
        frame, after a reset, for a frame with reset=True and when the resolution changed."""
        frame, _ = checked(as_frame(frame, fields), self.inputs, self.name, final=False)
        w, h = frame.size
        if frame.reset or self._history is None or self._shape != (h, w):
            return np.ones((h, w), bool)
        b = to_drjit(frame.buffers)
        grid = self._grid_for(w, h)
        best_i, velocity = self._velocity(grid, b)
        saved = (self._prev_depth, self._prev_ids)
        try:
            reject = self._rejection(grid, b, best_i, velocity)
        finally:
            self._prev_depth, self._prev_ids = saved
        inv = self._invalid(grid, b, velocity, reject)
        return np.asarray(inv, dtype=bool).reshape(h, w).copy()

    # -- per frame: the baseline's step, with the supersampled colour composited in ------------------
    def _composite(self, grid: K.Grid, b: dict, frame: Frame, blend, velocity, reject):
        p = self.params
        w, h = frame.size
        invalid = self._invalid(grid, b, velocity, reject)   # before the history changes
        need = np.asarray(invalid, dtype=bool).reshape(h, w)
        mask_np = need if frame.mask is None else frame.mask
        if np.any(need & ~mask_np):
            raise ValueError(f"the mask given to {self.name}.process misses "
                             f"{int(np.sum(need & ~mask_np))} pixel(s) the technique finds invalid "
                             f"(use invalid_mask() on the same frame, before process)")
        ss_np = np.where(mask_np[..., None], frame.supersampled, np.float32(0))
        bad = mask_np & ~np.isfinite(ss_np).all(axis=-1)
        if bad.any():   # never let a non-finite value into the history: use the current colour
            ss_np = np.where(bad[..., None], from_drjit_color(b["color"], h, w), ss_np)
        self.last_nonfinite["supersampled"] = int(bad.sum())
        self.last_nonfinite_count += int(bad.sum())
        m = array(mi.Bool, mask_np)
        out = dr.select(m, dr.unravel(mi.Color3f, array(mi.Float, ss_np)), blend)
        n_mask = int(mask_np.sum())
        self.last_stats = {"invalid_fraction": n_mask / float(w * h),
                           "extra_samples": n_mask * p.samples, "pixels": w * h}
        return out, {"invalid": mi.Float(dr.select(m, 1.0, 0.0)), "composite": out}


__all__ = ["SparseTAA", "SparseParams", "DIFFERENCES", "colour_difference"]

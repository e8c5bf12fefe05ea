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

Per frame: the baseline TAA runs everywhere unchanged (taa_impl/baseline.py with all TAAParams switches,
code mirrored from BaselineTAA._step); then out = supersampled where invalid, the TAA blend elsewhere;
that composite is the new history (so a re-rendered pixel restarts its history from an N-sample
estimate) and is sharpened for display exactly as the baseline's blend is.

Driver protocol (class attribute `supersampling = True`; study.engine.drive drives it):
  mask = tech.invalid_mask(frame, far=far)         # (H, W) bool, no state change
  supersampled = <mean of params.samples jittered samples, rendered where mask is set, 0 elsewhere>
  out = tech.process(frame, jitter=..., far=..., reset=..., supersampled=supersampled, mask=mask)
  tech.last_stats -> {"invalid_fraction", "extra_samples", "pixels"}
`mask` may be a superset of the technique's own invalid pixels (what the driver rendered); a mask
that misses one of them, or supersampled=None, is an error. Without `mask`, process uses its own.
With mu = inf only pixels without history are invalid, and where the supersampled colour equals the
frame's colour the result is the baseline TAA's, bit for bit (tested).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import backend  # noqa: F401
from backend import array, dr, mi

from . import kernels as K
from . import sanitize
from .base import TAAParams, from_drjit_color, sharpen_weight, to_drjit
from .baseline import BaselineTAA, fetch_history, resolve

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
    sampling = "sequence"
    supersampling = True

    def __init__(self, params=None, *, feedback: str | None = None, **overrides):
        super().__init__(params, feedback=feedback, **overrides)
        self.last_stats: dict = {}
        self._pending = None

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

    def _velocity(self, grid: K.Grid, b: dict):
        best_i = K.closest_index(grid, b["depth"])
        return best_i, dr.gather(mi.Vector2f, b["motion"], best_i)

    def invalid_mask(self, frame: dict, *, far: float, reset: bool = False) -> np.ndarray:
        """(H, W) bool: pixels of this frame that will need the supersampled colour, computed from
        the frame and the current history without changing any state. All True on the first
        frame, after a reset, with reset=True and when the resolution changed."""
        far = float(far)
        if not (math.isfinite(far) and far > 0):
            raise ValueError(f"far must be finite and > 0, got {far}")
        missing = self.needs - frame.keys()
        if missing:
            raise KeyError(f"{self.name} needs buffers {sorted(missing)}")
        h, w = np.shape(frame["color"])[:2]
        if reset or self._history is None or self._shape != (h, w):
            return np.ones((h, w), bool)
        bufs = sanitize.check_and_repair(frame, self.needs, (h, w), far)
        bufs.pop("_nonfinite")
        b = to_drjit(bufs)
        grid = self._grid_for(w, h)
        best_i, velocity = self._velocity(grid, b)
        saved = (self._prev_depth, self._prev_ids)
        try:
            reject = self._rejection(grid, b, best_i, velocity)
        finally:
            self._prev_depth, self._prev_ids = saved
        inv = self._invalid(grid, b, velocity, reject)
        return np.asarray(inv, dtype=bool).reshape(h, w).copy()

    # -- per frame -------------------------------------------------------------------------------
    def process(self, frame: dict, *, jitter, far: float, reset: bool = False, display=None,
                supersampled=None, mask=None) -> np.ndarray:
        """As Technique.process, plus the supersampled colour (required) and the driver's mask."""
        if supersampled is None:
            raise ValueError(f"{self.name} needs supersampled= (the (H, W, 3) mean of "
                             f"{self.params.samples} jittered samples at the pixels of "
                             f"invalid_mask()); the driver did not provide it")
        hw = np.shape(frame["color"])[:2]
        ss = np.asarray(supersampled, dtype=np.float32)
        if ss.shape != (*hw, 3):
            raise ValueError(f"supersampled has shape {ss.shape}, expected {(*hw, 3)}")
        if mask is not None:
            mask = np.asarray(mask, dtype=bool)
            if mask.shape != hw:
                raise ValueError(f"mask has shape {mask.shape}, expected {hw}")
        self._pending = (ss, mask)
        try:
            return super().process(frame, jitter=jitter, far=far, reset=reset, display=display)
        finally:
            self._pending = None

    def _step(self, b: dict, w: int, h: int, far: float):
        if self._pending is None:
            raise ValueError(f"{self.name}: call process(..., supersampled=...)")
        ss_np, mask_np = self._pending
        p = self.params
        grid = self._grid_for(w, h)
        # -- BaselineTAA._step, unchanged -------------------------------------------------------
        c = b["color"]
        best_i, velocity = self._velocity(grid, b)
        reject = self._rejection(grid, b, best_i, velocity)
        invalid = self._invalid(grid, b, velocity, reject)   # before the history changes
        bmin, bmax, bavg = self._box(grid, c)
        blend, valid = resolve(p, grid, c, self._history, velocity, bmin, bmax, reject)
        # -- the sparse supersampling composite -------------------------------------------------
        need = np.asarray(invalid, dtype=bool).reshape(h, w)
        if mask_np is None:
            mask_np = need
        elif np.any(need & ~mask_np):
            raise ValueError(f"the mask given to {self.name}.process misses "
                             f"{int(np.sum(need & ~mask_np))} pixel(s) the technique finds invalid "
                             f"(use invalid_mask() on the same frame, before process)")
        ss_np = np.where(mask_np[..., None], ss_np, np.float32(0))
        bad = mask_np & ~np.isfinite(ss_np).all(axis=-1)
        if bad.any():   # never let a non-finite value into the history: use the current colour
            c_np = from_drjit_color(c, h, w)
            ss_np = np.where(bad[..., None], c_np, ss_np)
        self.last_nonfinite["supersampled"] = int(bad.sum())
        self.last_nonfinite_count += int(bad.sum())
        m = array(mi.Bool, mask_np)
        ss = dr.unravel(mi.Color3f, array(mi.Float, ss_np))
        out = dr.select(m, ss, blend)
        dr.eval(out)
        self._history = out
        n_mask = int(mask_np.sum())
        self.last_stats = {"invalid_fraction": n_mask / float(w * h),
                           "extra_samples": n_mask * p.samples, "pixels": w * h}
        self._terms = {"velocity": velocity, "box_min": bmin, "box_max": bmax, "box_avg": bavg,
                       "history_valid": mi.Float(dr.select(valid, 1.0, 0.0)) if valid is not None
                       else dr.zeros(mi.Float, grid.n),
                       "invalid": mi.Float(dr.select(m, 1.0, 0.0)),
                       "blend": blend, "composite": out}
        if reject is not None:
            self._terms["history_rejected"] = mi.Float(dr.select(reject, 1.0, 0.0))
        return K.sharpen(grid, out, sharpen_weight(p.sharpen))


__all__ = ["SparseTAA", "SparseParams", "DIFFERENCES", "colour_difference"]

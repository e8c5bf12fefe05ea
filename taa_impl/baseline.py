"""Baseline TAA: Uncharted 4 (Xu 2016) / INSIDE (Pedersen 2016) as the thesis used it (Oliveros 2018, §3.6).

Sharpening is applied to the displayed output only; the history keeps the unsharpened blend (Xu runs
the sharpen as a separate pass after TAA, INSIDE's history is the plain blend). Sharpening the
history would compound the kernel every frame (with Xu's 5/-1 kernel it diverges).

The displayed output is max(sharpened blend, 0). The sharpen undershoots next to HDR edges (on
hdr_contrast, 1000 beside ~0, Xu's kernel gives -4000 and the normalised one -1000, at ~16 % of the
pixels at 96x54); a negative radiance cannot be displayed, and the display transform clamps at 0
anyway, so the 8-bit metrics (PSNR, SSIM, FLIP) are the same with or without this clamp. It
matters only for the linear-HDR relative MSE, which therefore judges the image that is shown
(a black pixel) rather than the undershoot's size. The history is not clamped: it lies in the
neighbourhood's colour range (the clip ends in a clamp into the box), so with the RGB box it is
>= 0 for inputs >= 0 (a YCoCg box can reach outside the RGB cube).

Step 4's clip carries a tolerance relative to the box's magnitude (TAAParams.clip_tol, 1e-4) on top
of INSIDE's eps, and ends in a clamp into the box: with eps alone float32 rounding decided the
clip (kernels.clip_toward_centre says how; clip_tol=0 gives INSIDE's clip).

The current colour c is the raster's jittered sample as is (the "un-jittered sample" of Xu 2016: we
do not resample it; jitter only moves where the sample was taken).

Extensions (Karis 2014, Salvi 2016 and the others named below), each a TAAParams switch whose
default is off (= the baseline above, bit for bit). They compose in this order, per pixel:
 1. velocity of the closest-depth 3x3 pixel (unchanged);
 2. box space: `box='ycocg'` converts the current colours to YCoCg (Karis 2014) and builds the box
    there; the history is converted, clipped in YCoCg and converted back to RGB (YCoCg is linear,
    so the blend is the same in either space; the clip is not);
 3. box shape: `variance_clip_gamma=g` replaces the min/max box by Salvi's mu -/+ g*sigma over the
    3x3 (in the box space of 2); `variance_intersect=True` intersects it with the min/max box
    instead (the variance box can reach beyond the colours present, e.g. below 0 next to one
    bright pixel; the intersection never does). The intersection is never empty: mu lies in both;
 4. history fetch: `history_filter='catmull_rom'` (exact 4x4 Catmull-Rom, = the 9-tap shader form)
    or 'catmull_rom_5' (5-tap approximation) instead of bilinear; their negative lobes are removed
    by the clip of step 5, which puts the history inside the box of current colours;
 5. rejection: `reject_depth=r` / `reject_id=True` drop the history of a pixel (it takes the current
    colour, as off-screen does) when the depth / object ID the history had at the reprojected
    position differs from what the followed surface had last frame (see TAATechnique._rejection);
 6. clip toward the box centre (unchanged), feedback k from linear luminances (unchanged);
 7. blend: `tonemap_blend=True` blends in Karis's c / (1 + luma(c)) space and maps back
    (implemented as the equivalent weight, kernels.karis_blend_weight); otherwise lerp(c, h, k);
 8. sharpen the output (unchanged; the history stays unsharpened).
"""
from __future__ import annotations

import dataclasses

import numpy as np

import backend  # noqa: F401
from backend import dr, mi

from . import kernels as K
from .base import Frame, Inputs, TAAParams, Technique, from_drjit_color, sharpen_weight, terms_to_numpy


def fetch_history(params: TAAParams, grid: K.Grid, history, velocity):
    """The history at each pixel's previous position with the configured filter, and `valid`."""
    if params.history_filter == "bilinear":
        return K.reproject(grid, history, velocity)
    px, py, valid = K.previous_position(grid, velocity)
    return K.catmull_rom(grid, history, px, py, five_tap=params.history_filter == "catmull_rom_5"), valid


def resolve(params: TAAParams, grid: K.Grid, c, history, velocity, bmin, bmax, reject=None):
    """Steps 2, 4, 5: reproject, clip toward the box centre, blend with luminance feedback.

    No history (first frame, reset), an off-screen reprojection or a rejected pixel (`reject`, a
    mask) gives c for that pixel. (bmin, bmax) are in YCoCg when params.box == 'ycocg'."""
    if history is None:
        return c, None
    h, valid = fetch_history(params, grid, history, velocity)
    if reject is not None:
        valid = valid & ~reject
    eps, tol = params.clip_eps, params.clip_tol
    if params.box == "ycocg":
        h = K.ycocg_to_rgb(K.clip_toward_centre(K.rgb_to_ycocg(h), bmin, bmax, eps, tol))
    else:
        h = K.clip_toward_centre(h, bmin, bmax, eps, tol)
    k = K.feedback_weight(K.luminance(c, params.feedback_luma), K.luminance(h, params.feedback_luma),
                          params.k_min, params.k_max, params.feedback_floor)
    if params.tonemap_blend:
        k = K.karis_blend_weight(c, h, k, params.tonemap_luma)
    return dr.select(valid, K.lerp(c, h, k), c), valid


class TAATechnique(Technique):
    """Shared plumbing of the TAAs: colour history, a cached pixel grid, debug terms, rejection."""

    contract = Inputs(sampling="sequence")

    @classmethod
    def inputs_for(cls, params=None) -> Inputs:
        """The class's contract plus the buffers its rejection tests read."""
        p = params if params is not None else cls.Params()
        extra = ({"prev_depth"} if p.reject_depth is not None else set()) | ({"object_id"} if p.reject_id else set())
        return dataclasses.replace(cls.contract, buffers=cls.contract.buffers | extra) if extra else cls.contract

    def _clear_history(self) -> None:
        self._history = None  # mi.Color3f: last unsharpened blend
        self._grid = None
        self._terms: dict = {}
        self._prev_depth = None  # previous frame's depth buffer (kept only when rejecting by depth)
        self._prev_ids = None    # previous frame's object IDs (kept only when rejecting by ID)

    def _rejection(self, grid: K.Grid, b: dict, best_i, velocity):
        """History rejection mask (True = drop the history), then keep this frame's buffers.

        The surface followed at a pixel is the closest-depth 3x3 pixel whose velocity is used
        (best_i). Last frame it had depth b['prev_depth'][best_i] and ID b['object_id'][best_i]; the
        history at the reprojected position (nearest texel) was made of whatever the stored depth /
        ID buffers show there. Depth: reject if |stored - expected| > reject_depth * expected.
        ID: reject if they differ. None when nothing is tested or there is no stored frame."""
        p = self.params
        if not p.rejects:
            return None
        reject = None
        if self._history is not None:
            px, py, _ = K.previous_position(grid, velocity)
            ni = K.nearest_index(grid, px, py)
            reject = dr.zeros(mi.Bool, grid.n)
            if p.reject_depth is not None and self._prev_depth is not None:
                stored = dr.gather(mi.Float, self._prev_depth, ni)
                expected = dr.gather(mi.Float, b["prev_depth"], best_i)
                reject |= dr.abs(stored - expected) > p.reject_depth * dr.abs(expected)
            if p.reject_id and self._prev_ids is not None:
                reject |= dr.gather(mi.Int32, self._prev_ids, ni) != dr.gather(mi.Int32, b["object_id"], best_i)
            dr.eval(reject)
        self._prev_depth = b["depth"] if p.reject_depth is not None else None
        self._prev_ids = b["object_id"] if p.reject_id else None
        return reject

    def _grid_for(self, w: int, h: int) -> K.Grid:
        if self._grid is None or (self._grid.w, self._grid.h) != (w, h):
            self._grid = K.Grid(w, h)
        return self._grid

    def debug_terms(self) -> dict[str, np.ndarray]:
        """Intermediate images of the last frame as NumPy (H, W[, C]) float32 arrays."""
        return terms_to_numpy(self._terms, *self._shape) if self._terms else {}

    @property
    def history(self) -> np.ndarray | None:
        """The stored (unsharpened) colour history as NumPy, or None after a reset."""
        if self._history is None:
            return None
        return from_drjit_color(self._history, *self._shape)


class BaselineTAA(TAATechnique):
    """The baseline of Oliveros 2018, §3.6, plus the extension switches of TAAParams (module docstring). The debug terms
    box_min / box_max / box_avg are in the box space (YCoCg when box='ycocg'; box_avg is mu with
    a variance box)."""
    name = "taa_baseline"
    Params = TAAParams
    contract = Inputs(buffers={"color", "depth", "motion"}, sampling="sequence")

    def _box(self, grid, c):
        """Neighbourhood box (min, max, mean) in the box space: min/max of 3x3 and cross, or
        Salvi's variance box, alone or intersected with it."""
        p = self.params
        cs = K.rgb_to_ycocg(c) if p.box == "ycocg" else c
        bmin, bmax, bavg = K.neighbourhood(grid, cs).averaged()
        if p.variance_clip_gamma is not None:
            vmin, vmax, bavg = K.variance_box(grid, cs, p.variance_clip_gamma)
            if p.variance_intersect:
                bmin, bmax = dr.maximum(bmin, vmin), dr.minimum(bmax, vmax)
            else:
                bmin, bmax = vmin, vmax
        return bmin, bmax, bavg

    def _velocity(self, grid: K.Grid, b: dict):
        """Step 1: the closest-depth 3x3 pixel and its motion."""
        best_i = K.closest_index(grid, b["depth"])
        return best_i, dr.gather(mi.Vector2f, b["motion"], best_i)

    def _composite(self, grid: K.Grid, b: dict, frame: Frame, blend, velocity, reject):
        """The new history from the blend (a hook, taa_impl.sparse): (history, its debug terms)."""
        return blend, {}

    def _step(self, b: dict, frame: Frame):
        p = self.params
        grid = self._grid_for(*frame.size)
        c = b["color"]
        best_i, velocity = self._velocity(grid, b)
        reject = self._rejection(grid, b, best_i, velocity)
        bmin, bmax, bavg = self._box(grid, c)
        blend, valid = resolve(p, grid, c, self._history, velocity, bmin, bmax, reject)
        history, extra = self._composite(grid, b, frame, blend, velocity, reject)
        dr.eval(history)
        self._history = history
        self._terms = {"velocity": velocity, "box_min": bmin, "box_max": bmax, "box_avg": bavg,
                       "history_valid": mi.Float(dr.select(valid, 1.0, 0.0)) if valid is not None
                       else dr.zeros(mi.Float, grid.n),
                       "blend": blend, **extra}
        if reject is not None:
            self._terms["history_rejected"] = mi.Float(dr.select(reject, 1.0, 0.0))
        return K.sharpen(grid, history, sharpen_weight(p.sharpen))

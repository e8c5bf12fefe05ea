"""Temporal and spatial upscaling: techniques that render at `render_scale` x the output's size and
output at the output's size, judged against the output-size reference like every other technique.

The driver renders an upscaler's frames at `render_size(W, H, scale)` over the output's frustum
(raster.Rasterizer(aspect=)), jittered with the technique's own phase count (`Inputs.jitter_period`),
and hands them over with the output's size (`Frame.output_size = (W, H)`; its contract `upsamples`). Buffers (colour, depth, motion)
come at the render resolution, motion in render pixels, as engines hand them to an upscaler.

Coordinates: output pixel (X, Y) has its centre at (X + 0.5, Y + 0.5) output pixels, i.e. at
((X + 0.5) rw / W, (Y + 0.5) rh / H) render pixels; render pixel (x, y)'s sample was taken at
(x + 0.5 + jx, y + 0.5 + jy) render pixels (the jitter moves the sample, taa_impl.base).

Here: the base class, the Lanczos-2 kernel and samplers, and the spatial floor (No AA upsampled,
bilinear or Lanczos-2). taa_impl.taau is a plain TAAU, taa_impl.fsr2 an FSR 2-class upscaler.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

import backend  # noqa: F401
from backend import dr, mi, opaque

from . import kernels as K
from .base import Frame, Inputs, Technique, terms_to_numpy
from .contract import check_scale, render_size  # noqa: F401  (render_size: this module's, as before)


def fsr2_phase_count(render_width: float, output_width: float) -> int:
    """FSR 2's jitter phase count: int(8 (output / render)^2), truncated (8, 18, 23, 32, 72 at
    ratios 1, 1.5, 1.7, 2, 3; the +1e-6 keeps an exact ratio from rounding down)."""
    return max(1, int(8.0 * (output_width / render_width) ** 2 + 1e-6))


def lanczos2(x):
    """Lanczos-2: sinc(x) sinc(x / 2) for |x| < 2, else 0 (sinc(x) = sin(pi x) / (pi x)); 1 at 0."""
    ax = dr.abs(x)
    px = math.pi * ax
    small = ax < 1e-4
    w = 2.0 * dr.sin(px) * dr.sin(px * 0.5) / dr.select(small, 1.0, px * px)
    return dr.select(ax >= 2.0, 0.0, dr.select(small, 1.0, w))


def lanczos2_sample(grid: K.Grid, img, px, py, dering: bool = True):
    """`img` (on `grid`) at continuous positions (px, py) in its pixel units, with the separable
    4x4 Lanczos-2 filter, weights normalised to sum 1, clamp-to-edge. `dering`: clamp into the
    min/max of the 2x2 nearest texels (the filter's negative lobes ring at edges)."""
    x0, y0, tx, ty = K._texel_coords(grid, px, py)
    wx = [lanczos2(tx + 1.0), lanczos2(tx), lanczos2(1.0 - tx), lanczos2(2.0 - tx)]
    wy = [lanczos2(ty + 1.0), lanczos2(ty), lanczos2(1.0 - ty), lanczos2(2.0 - ty)]
    sx, sy = wx[0] + wx[1] + wx[2] + wx[3], wy[0] + wy[1] + wy[2] + wy[3]
    ref = K.texel(grid, img, x0, y0)
    out = None
    for j in range(4):
        row = None
        for i in range(4):
            v = (K.texel(grid, img, x0 + (i - 1), y0 + (j - 1)) - ref) * wx[i]
            row = v if row is None else row + v
        out = row * wy[j] if out is None else out + row * wy[j]
    out = ref + out / (sx * sy)          # deviations from one texel: a constant image stays exact
    if dering:
        t = [K.texel(grid, img, x0 + i, y0 + j) for j in (0, 1) for i in (0, 1)]
        lo = dr.minimum(dr.minimum(t[0], t[1]), dr.minimum(t[2], t[3]))
        hi = dr.maximum(dr.maximum(t[0], t[1]), dr.maximum(t[2], t[3]))
        out = dr.clip(out, lo, hi)
    return out


@dataclass(frozen=True)
class Frames:
    """One upscaler step's grids and the output pixels' positions in render pixels."""
    render: K.Grid
    output: K.Grid
    ux: object        # mi.Float: output pixel centres in render pixel units
    uy: object
    sx: float         # render / output pixels, per axis
    sy: float
    rx: object        # opaque mi.Float 1 / sx, 1 / sy: `v * rx` is `v / sx` (K.opaque_rcp)
    ry: object
    near: object      # mi.Int32: the render pixel each output pixel's centre lies in (flat index)
    nx: object        # ... and its (x, y)
    ny: object

    @classmethod
    def of(cls, rw: int, rh: int, w: int, h: int) -> "Frames":
        """The grids and positions for render size rw x rh and output size w x h, evaluated once
        (the scale factors are opaque: a new size compiles no new kernel)."""
        r, o = K.Grid(rw, rh), K.Grid(w, h)
        sx, sy = rw / w, rh / h
        ux = (mi.Float(o.x) + 0.5) * K.opaque_float(sx)
        uy = (mi.Float(o.y) + 0.5) * K.opaque_float(sy)
        xi = mi.Int32(dr.floor(dr.clip(ux, 0.0, r.Wf)))
        yi = mi.Int32(dr.floor(dr.clip(uy, 0.0, r.Hf)))
        nx, ny = dr.clip(xi, 0, r.W - 1), dr.clip(yi, 0, r.H - 1)
        near = ny * r.W + nx                # = K.nearest_index(r, ux, uy)
        dr.eval(ux, uy, nx, ny, near)
        return cls(r, o, ux, uy, sx, sy, K.opaque_rcp(sx), K.opaque_rcp(sy), near, nx, ny)

    def nearest(self):
        """Flat index of the render pixel each output pixel's centre lies in."""
        return self.near


class Upscaler(Technique):
    """Base class: the technique's Params has `render_scale`; its frames come with `output_size`.
    A subclass implements `_upscale(b, grids, frame, jitter)` (grids: this step's `Frames`; jitter:
    opaque Dr.Jit scalars)."""

    contract = Inputs(buffers={"color"}, upsamples=True)

    @classmethod
    def inputs_for(cls, params=None) -> Inputs:
        p = params if params is not None else cls.Params()
        return dataclasses.replace(cls.contract, render_scale=float(p.render_scale), upsamples=True,
                                   jitter_period=cls.jitter_period(p))

    @classmethod
    def jitter_period(cls, params) -> int:
        """The jitter's phase count ('sequence'): the TAAs' 16."""
        return 16

    def _step(self, b: dict, frame: Frame):
        if self._frames is None:
            self._frames = Frames.of(*frame.size, *frame.output_size)
        # opaque: a literal jitter would make each phase's kernels new, to be compiled again
        jx, jy = frame.jitter
        return self._upscale(b, self._frames, frame, (opaque(mi.Float, jx), opaque(mi.Float, jy)))

    def _clear_history(self) -> None:
        self._frames = None
        self._terms: dict = {}
        self._clear_state()

    def _clear_state(self) -> None:
        pass

    def _upscale(self, b: dict, fr: Frames, frame: Frame, jitter):
        raise NotImplementedError

    def debug_terms(self) -> dict[str, np.ndarray]:
        """The last frame's per-output-pixel intermediates as NumPy (H, W[, C]) float32 arrays."""
        return terms_to_numpy(self._terms, *self._shape) if self._terms else {}


SPATIAL_FILTERS = ("bilinear", "lanczos2")


@dataclass(frozen=True)
class SpatialParams:
    render_scale: float = 0.5
    filter: str = "lanczos2"       # 'bilinear' | 'lanczos2' (with a 2x2 dering clamp)

    def __post_init__(self):
        object.__setattr__(self, "render_scale", check_scale(self.render_scale))
        if self.filter not in SPATIAL_FILTERS:
            raise ValueError(f"filter must be one of {SPATIAL_FILTERS}, got {self.filter!r}")


class SpatialUpscale(Upscaler):
    """The floor: No AA rendered at the render scale (pixel centres, no jitter), upsampled in space
    alone. At render_scale 1 both filters give No AA's image exactly (each output pixel centre is a
    texel centre)."""
    name = "upscale_spatial"
    Params = SpatialParams
    contract = Inputs(buffers={"color"}, sampling="centre", upsamples=True)

    def _upscale(self, b, fr, frame, jitter):
        c = b["color"]
        if self.params.filter == "bilinear":
            return K.bilinear(fr.render, c, fr.ux, fr.uy)
        return dr.maximum(lanczos2_sample(fr.render, c, fr.ux, fr.uy), 0.0)

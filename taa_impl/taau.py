"""A plain temporal upsampler (TAAU, as UE4's): the baseline TAA's history kept at the output
resolution, the current frame's jittered render samples filtered onto it.

Per output pixel, with u its centre in render pixels (taa_impl.upscale):
 1. velocity: the render frame's closest-depth 3x3 velocity (as the baseline TAA), read at the
    render pixel u lies in and scaled to output pixels;
 2. current colour: the 3x3 render samples around that pixel, each at its jittered position s_i,
    weighted w_i = exp(-|s_i - u|^2 / (2 sigma^2)) with the distance in output pixels (sigma 0.47:
    the Gaussian fit of the Blackman-Harris window UE4 uses), normalised;
 3. box: the baseline TAA's (INSIDE's mean of the 3x3 and cross min/max) around that render pixel;
 4. history: bilinear at the output-resolution previous position, clipped toward the box centre
    (taa_impl.kernels.clip_toward_centre), INSIDE's luminance feedback k;
 5. blend: out = lerp(current, history, k'), with the current frame's weight 1 - k' = (1 - k) max_i w_i
    when `confidence` is on: a pixel no sample landed near this frame leans on its history (at a
    render scale of 0.5 only one output pixel in four has a sample within half an output pixel);
 6. sharpen (default none) on the output; the history keeps the blend.
No history (first frame, reset) or an off-screen reprojection gives the current colour.
"""
from __future__ import annotations

from dataclasses import dataclass

import backend  # noqa: F401
from backend import dr, mi

from . import kernels as K
from .base import Inputs, TAAParams, sharpen_weight
from .upscale import Upscaler, check_scale


TAAU_FILTERS = ("box", "gaussian")


@dataclass(frozen=True)
class TAAUParams(TAAParams):
    sharpen: str = "none"
    render_scale: float = 0.5
    filter: str = "box"            # step 2: 'box' (samples inside the output pixel) | 'gaussian'
    sigma: float = 0.47            # the 'gaussian' filter's width, output pixels
    confidence: bool = True        # step 5

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "render_scale", check_scale(self.render_scale))
        if not (float(self.sigma) > 0 and float(self.sigma) < 10):
            raise ValueError(f"sigma must be in (0, 10) output pixels, got {self.sigma!r}")
        if self.box != "minmax" or self.variance_clip_gamma is not None or self.history_filter != "bilinear" \
                or self.tonemap_blend or self.rejects:
            raise ValueError("TAAU takes the baseline TAA's min/max box, bilinear history, plain blend and no "
                             "rejection (the extension switches are not implemented for it)")
        object.__setattr__(self, "confidence", bool(self.confidence))
        if self.filter not in TAAU_FILTERS:
            raise ValueError(f"filter must be one of {TAAU_FILTERS}, got {self.filter!r}")


class TAAU(Upscaler):
    name = "taau"
    Params = TAAUParams
    contract = Inputs(buffers={"color", "depth", "motion"}, sampling="sequence", upsamples=True)

    def _clear_state(self) -> None:
        self._history = None

    def reconstruct(self, fr, c, jitter):
        """Steps 2-3: the filtered current colour, its box and the largest sample weight."""
        p = self.params
        near = fr.nearest()
        bmin, bmax, _ = K.neighbourhood(fr.render, c).averaged()
        bmin, bmax = dr.gather(mi.Color3f, bmin, near), dr.gather(mi.Color3f, bmax, near)
        nx, ny = fr.nx, fr.ny
        inv2s2 = 1.0 / (2.0 * float(p.sigma) ** 2)
        acc = wsum = wmax = None
        for dx, dy in K.OFFSETS_3X3:
            xi = dr.clip(nx + dx, 0, fr.render.W - 1)
            yi = dr.clip(ny + dy, 0, fr.render.H - 1)
            col = dr.gather(mi.Color3f, c, yi * fr.render.W + xi)
            # the sample's offset from the output pixel centre, in output pixels
            ox = (mi.Float(xi) + 0.5 + jitter[0] - fr.ux) * fr.rx
            oy = (mi.Float(yi) + 0.5 + jitter[1] - fr.uy) * fr.ry
            if p.filter == "box":
                w = dr.select((dr.abs(ox) <= 0.5) & (dr.abs(oy) <= 0.5), 1.0, 0.0)
            else:
                w = dr.exp(-(ox * ox + oy * oy) * inv2s2)
            if acc is None:
                acc, wsum, wmax = col * w, w, w
            else:
                acc, wsum, wmax = acc + col * w, wsum + w, dr.maximum(wmax, w)
        # no sample in the pixel ('box'; or all underflow): the nearest sample stands in for the box
        # and a first frame, and the confidence (0) leaves the history alone
        cur = dr.select(wsum > 1e-30, acc / dr.maximum(wsum, 1e-30), dr.gather(mi.Color3f, c, near))
        return dr.clip(cur, bmin, bmax), bmin, bmax, wmax

    def _upscale(self, b, fr, frame, jitter):
        p = self.params
        best = K.closest_index(fr.render, b["depth"])
        vel_r = dr.gather(mi.Vector2f, b["motion"], best)
        vel_r = dr.gather(mi.Vector2f, vel_r, fr.nearest())
        velocity = mi.Vector2f(vel_r.x * fr.rx, vel_r.y * fr.ry)
        cur, bmin, bmax, wmax = self.reconstruct(fr, b["color"], jitter)
        if self._history is None:
            blend, valid = cur, None
        else:
            h, valid = K.reproject(fr.output, self._history, velocity)
            h = K.clip_toward_centre(h, bmin, bmax, p.clip_eps, p.clip_tol)
            k = K.feedback_weight(K.luminance(cur, p.feedback_luma), K.luminance(h, p.feedback_luma),
                                  p.k_min, p.k_max, p.feedback_floor)
            if p.confidence:     # k + (1 - k)(1 - w): exactly k where a sample fills the pixel
                k = k + (1.0 - k) * (1.0 - wmax)
            blend = dr.select(valid, K.lerp(cur, h, k), cur)
        dr.eval(blend)
        self._history = blend
        self._terms = {"velocity": velocity, "current": cur, "confidence": wmax, "blend": blend,
                       "history_valid": mi.Float(dr.select(valid, 1.0, 0.0)) if valid is not None
                       else dr.zeros(mi.Float, fr.output.n)}
        return K.sharpen(fr.output, blend, sharpen_weight(p.sharpen))

"""The thesis's improved TAA (Oliveros 2018, Improved Sampling for Temporal Anti-Aliasing, §4.3).

The baseline's clip box is shrunk toward the current colour wherever a pixel does not look aliased.
"Aliased" (aliasedValue in [0, 1]) combines: the fraction of 3x3 pixels of another model
(modelAverage), depth pseudo-variances (spatial and temporal), and a temporally filtered Sobel of
albedo luminance, colour luminance and depth.

Choices the thesis leaves open, made here:
- Depth is normalised as z / far (the thesis's threshold 0.002 is in that unit) for the depth
  statistics and for the depth Sobel; `far` comes with every frame.
- d_prev (depthTPV) is the frame's `prev_depth`: the depth the *same surface point* had in the
  previous frame (the raster computes it with the point's previous transform), i.e. it is
  reprojected along the true motion, not read from the previous depth buffer at the same pixel.
- The Sobel image's own TAA uses the colour's velocity and the same feedback (k_min, k_max, floor);
  "luminance" of a one-channel image is its value; the history is clamped to the averaged
  3x3/cross box (the thesis: clamp instead of clip); no sharpen.
- Sharpening, as in the baseline, applies to the displayed output only (history is unsharpened).
- The history is clipped into the thesis's box by the baseline's clip, with its tolerance
  (TAAParams.clip_tol; kernels.clip_toward_centre), and the output is clamped at 0 likewise.

Extensions: the resolve-stage switches of TAAParams (history_filter, tonemap_blend, reject_depth,
reject_id) apply here exactly as in the baseline (the Sobel image's own TAA keeps its bilinear
fetch and no rejection). The box switches (box='ycocg', variance_clip_gamma) are defined for the
baseline's box only and are refused: the thesis's box is its own construction.
"""
from __future__ import annotations

from dataclasses import dataclass

import backend  # noqa: F401
from backend import dr, mi

from . import kernels as K
from .base import Frame, Inputs, TAAParams, sharpen_weight
from .baseline import TAATechnique, resolve


@dataclass(frozen=True)
class ImprovedParams(TAAParams):
    sharpen: str = "normalised"                 # thesis eq. 4.13
    depth_threshold: float = 0.002              # on normalised depth z/far (thesis §4.3.2)
    sobel_weight_albedo: float = 0.3            # u, thesis eq. 4.5
    sobel_weight_color: float = 0.7             # l
    sobel_weight_depth: float = 1.0             # d
    sobel_luma: tuple[float, float, float] = K.REC709

    def __post_init__(self):
        super().__post_init__()
        if self.box != "minmax" or self.variance_clip_gamma is not None:
            raise ValueError("box='ycocg' and variance_clip_gamma are baseline-TAA extensions; the "
                             "improved TAA builds its own box (thesis eq. 4.11-4.12)")
        if not self.depth_threshold >= 0:
            raise ValueError("depth_threshold must be >= 0")
        object.__setattr__(self, "sobel_luma", tuple(float(v) for v in self.sobel_luma))


class ImprovedTAA(TAATechnique):
    name = "taa_improved"
    Params = ImprovedParams
    contract = Inputs(buffers={"color", "albedo", "depth", "prev_depth", "object_id", "motion"}, sampling="sequence")

    def _clear_history(self) -> None:
        super()._clear_history()
        self._sobel_history = None  # mi.Float: last output of the Sobel image's TAA

    def _sobel_taa(self, grid: K.Grid, s_raw, velocity):
        """The simplified TAA of the Sobel image (one channel, clamp, no sharpen)."""
        p = self.params
        if self._sobel_history is None:
            return s_raw, None
        smin, smax, _ = K.neighbourhood(grid, s_raw).averaged()
        hs, valid = K.reproject(grid, self._sobel_history, velocity)
        hs = dr.clip(hs, smin, smax)
        k = K.feedback_weight(s_raw, hs, p.k_min, p.k_max, p.feedback_floor)
        return dr.select(valid, K.lerp(s_raw, hs, k), s_raw), valid

    def _step(self, b: dict, frame: Frame):
        p = self.params
        grid = self._grid_for(*frame.size)
        inv_far = K.opaque_rcp(frame.far)   # opaque: `far` changes between calls (same as / far)
        c = b["color"]
        zn = b["depth"] * inv_far        # normalised linear depth
        zp = b["prev_depth"] * inv_far
        best_i = K.closest_index(grid, b["depth"])
        velocity = dr.gather(mi.Vector2f, b["motion"], best_i)
        reject = self._rejection(grid, b, best_i, velocity)

        # Sobel (runs first, thesis §4.3.3): g = clamp01(0.3u + 0.7l + d); sobel = sqrt(smoothstep).
        u = K.sobel(grid, K.luminance(b["albedo"], p.sobel_luma))
        l = K.sobel(grid, K.luminance(c, p.sobel_luma))
        d = K.sobel(grid, zn)
        g = K.clamp01(p.sobel_weight_albedo * u + p.sobel_weight_color * l + p.sobel_weight_depth * d)
        s_raw = dr.sqrt(g * g * (3.0 - 2.0 * g))
        dr.eval(s_raw)
        s_taa, _ = self._sobel_taa(grid, s_raw, velocity)
        dr.eval(s_taa)
        self._sobel_history = s_taa
        sobel = s_taa
        sobel_cross, sobel_3x3 = K.mean_cross(grid, s_taa), K.mean3x3(grid, s_taa)

        # modelAverage (eq. 4.1): pixels of another model among the 9, centre included, / 9.
        ids = b["object_id"]
        n_other = mi.Float(0.0)
        for o in K.OFFSETS_3X3:
            n_other += dr.select(grid.tap(ids, *o) != ids, 1.0, 0.0)
        model_avg = n_other / 9.0

        # Depth pseudo-variances (eqs. 4.2-4.4), zero where the 3x3 depths are closer than the threshold.
        dn = K.neighbourhood(grid, zn)
        dmin, dmax, davg = dn.min3, dn.max3, dn.avg3
        mdd = dr.minimum(dr.abs(dmin - davg), dr.abs(dmax - davg))
        gate = (mdd >= p.depth_threshold) & (mdd > 0)   # mdd > 0 only matters if threshold == 0
        safe = dr.select(gate, mdd, 1.0)
        depth_pv = dr.select(gate, dr.square(dr.abs(zn - davg) / safe), 0.0)
        depth_tpv = dr.select(gate, dr.square(dr.square(dr.abs(zp - davg) / safe)), 0.0)

        # Final mixing (eqs. 4.8-4.12).
        mix_val = K.clamp01(model_avg + sobel)
        sobel_avg = K.lerp(sobel_cross, sobel_3x3, mix_val)
        aliased = K.clamp01(sobel_avg + depth_pv + depth_tpv + model_avg)
        cmin, cmax, cavg = K.neighbourhood(grid, c).mixed(aliased)
        clip_min, clip_max = K.lerp(c, cmin, aliased), K.lerp(c, cmax, aliased)

        blend, valid = resolve(p, grid, c, self._history, velocity, clip_min, clip_max, reject)
        dr.eval(blend)
        self._history = blend
        self._terms = {
            "velocity": velocity, "modelAverage": model_avg, "maxDepthDistance": mdd,
            "depthPV": depth_pv, "depthTPV": depth_tpv, "sobel_raw": s_raw, "sobel": sobel,
            "sobelAvgCross": sobel_cross, "sobelAvg3x3": sobel_3x3, "sobelAvgMixVal": mix_val,
            "sobelAvg": sobel_avg, "aliasedValue": aliased, "colorMin": cmin, "colorMax": cmax,
            "colorAvg": cavg, "clipMin": clip_min, "clipMax": clip_max,
            "history_valid": mi.Float(dr.select(valid, 1.0, 0.0)) if valid is not None
            else dr.zeros(mi.Float, grid.n),
            "blend": blend,
        }
        if reject is not None:
            self._terms["history_rejected"] = mi.Float(dr.select(reject, 1.0, 0.0))
        return K.sharpen(grid, blend, sharpen_weight(p.sharpen))

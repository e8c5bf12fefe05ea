"""FXAA: Lottes' FXAA 3.11, the PC "quality" algorithm (FxaaPixelShader with FXAA_PC = 1), in Dr.Jit.

Written from NVIDIA's published FXAA 3.11 description; one pass, every pixel independently:
 1. luma of M (centre) and N, S, E, W; range = max - min; early exit (pixel unchanged) when
    range < max(edge_threshold_min, max * edge_threshold);
 2. corners NW, NE, SW, SE; subpixel aliasing: |lowpass - M| / range with the 3x3 lowpass
    (2 * (N + S + E + W) + corners) / 12, shaped as smoothstep^2 and scaled by `subpix`;
 3. horizontal vs vertical edge from |second differences| weighted 1-2-1 across the rows / columns
    (ties go horizontal), then the pixel pair: the neighbour across the edge with the larger
    gradient (ties go N / W);
 4. search along the edge in both directions, on the line half a pixel toward the pair (so a
    bilinear tap reads the pair's average luma), stepping by the preset's table; an end is found
    where |luma_end - pair average| >= gradient / 4;
 5. offset from the closer end: 0.5 - dist / span length, used only if the luma at that end moves
    in the right direction (else 0); take max(edge offset, subpixel offset);
 6. one bilinear fetch of the colour at the pixel centre moved by that offset across the edge.

Choices made here (FXAA leaves them to the integrator):
- Input: the display image, `display.encode(colour)` (tone map + sRGB, floats in [0, 1]), as FXAA
  expects perceptual, gamma-encoded values; the output is that image anti-aliased
  (output_space = 'display'), and the driver quantises it without tone-mapping again.
- Luma (`luma`): 'rec601' (default) = dot(encoded RGB, (0.299, 0.587, 0.114)), exactly the luma
  FXAA 3.11's integration notes tell you to store in alpha (FXAA_GREEN_AS_LUMA = 0);
  'green' = the encoded green channel (FXAA_GREEN_AS_LUMA = 1; blind to pure red/blue edges).
- Coordinates are in pixels (rcpFrame = 1), texel centres at +0.5; taps use clamp-to-edge
  addressing (a search that leaves the image keeps reading the border texels); bilinear weights
  are exact floats (GPU samplers quantise them to 8 bits).
- The output is clamped to [0, 1] (a bilinear mix of [0, 1] values, only rounding could leave it).
- Defaults: preset 39 (12 steps 1, 1, 1, 1, 1, 1.5, 2, 2, 2, 2, 4, 8: the highest quality),
  subpix 0.75 (FXAA's default), edge_threshold 0.125 ("high quality"; 0.063 "overkill" allowed),
  edge_threshold_min 0.0312 ("visible limit"; 0.0625 "high quality, faster" allowed).

What it does to a long straight edge: the search runs to its maximum on both sides, the pixel sits
in the middle of the span, so the edge offset is 0.5 - span/2/span = 0; only the subpixel term
acts. For a horizontal step (rows above colour A, below colour B) the two rows next to the step have
|lowpass - M| / range = 1/3, so both are moved toward each other by subpix * smoothstep(1/3)^2 =
0.75 * (7/27)^2 = 0.0504 of the difference; every other pixel exits early, unchanged. With
subpix = 0 a straight edge is left exactly as it is.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import backend  # noqa: F401
from backend import dr, mi

from . import kernels as K
from .base import DisplayImageTechnique

# FXAA_QUALITY__P0 .. P(PS-1) of FXAA 3.11's quality presets (10-15 medium dither, 20-29 low
# dither, 39 extreme quality, no dither).
FXAA_QUALITY_PRESETS: dict[int, tuple[float, ...]] = {
    10: (1.5, 3.0, 12.0),
    11: (1.0, 1.5, 3.0, 12.0),
    12: (1.0, 1.5, 2.0, 4.0, 12.0),
    13: (1.0, 1.5, 2.0, 2.0, 4.0, 12.0),
    14: (1.0, 1.5, 2.0, 2.0, 2.0, 4.0, 12.0),
    15: (1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 4.0, 12.0),
    20: (1.5, 2.0, 8.0),
    21: (1.0, 1.5, 2.0, 8.0),
    22: (1.0, 1.5, 2.0, 2.0, 8.0),
    23: (1.0, 1.5, 2.0, 2.0, 2.0, 8.0),
    24: (1.0, 1.5, 2.0, 2.0, 2.0, 3.0, 8.0),
    25: (1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 4.0, 8.0),
    26: (1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 2.0, 4.0, 8.0),
    27: (1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 4.0, 8.0),
    28: (1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 4.0, 8.0),
    29: (1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 4.0, 8.0),
    39: (1.0, 1.0, 1.0, 1.0, 1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 4.0, 8.0),
}
LUMAS = {"rec601": (0.299, 0.587, 0.114), "green": (0.0, 1.0, 0.0)}


@dataclass(frozen=True)
class FXAAParams:
    preset: int = 39                      # FXAA_QUALITY__PRESET: its search step table
    subpix: float = 0.75                  # fxaaQualitySubpix (0 = off ... 1 = softest)
    edge_threshold: float = 0.125         # fxaaQualityEdgeThreshold
    edge_threshold_min: float = 0.0312    # fxaaQualityEdgeThresholdMin
    luma: str = "rec601"                  # 'rec601' (luma in alpha) | 'green' (FXAA_GREEN_AS_LUMA)

    def __post_init__(self):
        if self.preset not in FXAA_QUALITY_PRESETS:
            raise ValueError(f"preset must be one of {sorted(FXAA_QUALITY_PRESETS)}")
        if not 0.0 <= self.subpix <= 1.0:
            raise ValueError("subpix must be in [0, 1]")
        if not (0.0 < self.edge_threshold <= 1.0 and 0.0 < self.edge_threshold_min <= 1.0):
            raise ValueError("edge thresholds must be in (0, 1]")
        if self.luma not in LUMAS:
            raise ValueError(f"luma must be one of {sorted(LUMAS)}")

    @property
    def steps(self) -> tuple[float, ...]:
        return FXAA_QUALITY_PRESETS[self.preset]


class EncodedDisplay:
    """A stand-in DisplayTransform for frames whose colour is already display-encoded: encode()
    only clamps to [0, 1]. (Tests and callers that run FXAA on an existing display image.)"""

    @staticmethod
    def encode(rgb):
        return np.clip(np.asarray(rgb, np.float32), 0.0, 1.0)


ENCODED = EncodedDisplay()


class FXAA(DisplayImageTechnique):
    """debug_terms(): luma, early_exit, horz_span, pixel_offset (the final offset in pixels,
    signed along the edge normal)."""
    name = "fxaa"
    Params = FXAAParams

    @staticmethod
    def kernel(grid, rgb, params):
        return fxaa(grid, rgb, params)


def fxaa(grid: K.Grid, rgb, p: FXAAParams):
    """FXAA 3.11 quality on the display-encoded image `rgb` (mi.Color3f); returns (image, terms)."""
    luma = K.luminance(rgb, LUMAS[p.luma])
    dr.eval(luma)
    tap = grid.tap
    lumaM = luma
    lumaS, lumaE, lumaN, lumaW = tap(luma, 0, 1), tap(luma, 1, 0), tap(luma, 0, -1), tap(luma, -1, 0)

    # 1. local contrast, early exit
    range_max = dr.maximum(dr.maximum(lumaN, lumaW), dr.maximum(lumaE, dr.maximum(lumaS, lumaM)))
    range_min = dr.minimum(dr.minimum(lumaN, lumaW), dr.minimum(lumaE, dr.minimum(lumaS, lumaM)))
    rng = range_max - range_min
    early_exit = rng < dr.maximum(p.edge_threshold_min, range_max * p.edge_threshold)

    # 2./3. corners, edge direction, subpixel lowpass
    lumaNW, lumaSE = tap(luma, -1, -1), tap(luma, 1, 1)
    lumaNE, lumaSW = tap(luma, 1, -1), tap(luma, -1, 1)
    lumaNS, lumaWE = lumaN + lumaS, lumaW + lumaE
    subpix_rcp_range = 1.0 / dr.maximum(rng, 1e-30)   # rng = 0 only where the pixel exits early
    subpixNSWE = lumaNS + lumaWE
    edge_horz1 = -2.0 * lumaM + lumaNS
    edge_vert1 = -2.0 * lumaM + lumaWE
    lumaNESE, lumaNWNE = lumaNE + lumaSE, lumaNW + lumaNE
    edge_horz2 = -2.0 * lumaE + lumaNESE
    edge_vert2 = -2.0 * lumaN + lumaNWNE
    lumaNWSW, lumaSWSE = lumaNW + lumaSW, lumaSW + lumaSE
    edge_horz4 = dr.abs(edge_horz1) * 2.0 + dr.abs(edge_horz2)
    edge_vert4 = dr.abs(edge_vert1) * 2.0 + dr.abs(edge_vert2)
    edge_horz3 = -2.0 * lumaW + lumaNWSW
    edge_vert3 = -2.0 * lumaS + lumaSWSE
    edge_horz = dr.abs(edge_horz3) + edge_horz4
    edge_vert = dr.abs(edge_vert3) + edge_vert4
    subpixNWSWNESE = lumaNWSW + lumaNESE
    horz = edge_horz >= edge_vert
    subpixA = subpixNSWE * 2.0 + subpixNWSWNESE
    lumaN = dr.select(horz, lumaN, lumaW)          # the two neighbours across the edge
    lumaS = dr.select(horz, lumaS, lumaE)
    subpixB = subpixA * (1.0 / 12.0) - lumaM
    gradientN, gradientS = lumaN - lumaM, lumaS - lumaM
    lumaNN, lumaSS = lumaN + lumaM, lumaS + lumaM
    pairN = dr.abs(gradientN) >= dr.abs(gradientS)
    gradient = dr.maximum(dr.abs(gradientN), dr.abs(gradientS))
    length_sign = dr.select(pairN, -1.0, 1.0)      # toward the pair (rcpFrame = 1 pixel)
    subpixC = K.clamp01(dr.abs(subpixB) * subpix_rcp_range)

    # 4. search along the edge
    posMx, posMy = mi.Float(grid.x) + 0.5, mi.Float(grid.y) + 0.5
    offx = dr.select(horz, 1.0, 0.0)
    offy = dr.select(horz, 0.0, 1.0)
    posBx = dr.select(horz, posMx, posMx + length_sign * 0.5)
    posBy = dr.select(horz, posMy + length_sign * 0.5, posMy)
    steps = p.steps
    posNx, posNy = posBx - offx * steps[0], posBy - offy * steps[0]
    posPx, posPy = posBx + offx * steps[0], posBy + offy * steps[0]
    subpixD = -2.0 * subpixC + 3.0
    luma_end_n = K.bilinear(grid, luma, posNx, posNy)
    subpixE = subpixC * subpixC
    luma_end_p = K.bilinear(grid, luma, posPx, posPy)
    lumaNN = dr.select(pairN, lumaNN, lumaSS)      # twice the pair's average luma
    gradient_scaled = gradient * 0.25
    lumaMM = lumaM - lumaNN * 0.5
    subpixF = subpixD * subpixE
    luma_m_lt_zero = lumaMM < 0.0
    luma_end_n = luma_end_n - lumaNN * 0.5
    luma_end_p = luma_end_p - lumaNN * 0.5
    done_n = dr.abs(luma_end_n) >= gradient_scaled
    done_p = dr.abs(luma_end_p) >= gradient_scaled
    posNx = dr.select(done_n, posNx, posNx - offx * steps[1])
    posNy = dr.select(done_n, posNy, posNy - offy * steps[1])
    posPx = dr.select(done_p, posPx, posPx + offx * steps[1])
    posPy = dr.select(done_p, posPy, posPy + offy * steps[1])
    for step in steps[2:]:
        # (the shader skips the rest once both ends are found; per side this is the same)
        luma_end_n = dr.select(done_n, luma_end_n, K.bilinear(grid, luma, posNx, posNy) - lumaNN * 0.5)
        luma_end_p = dr.select(done_p, luma_end_p, K.bilinear(grid, luma, posPx, posPy) - lumaNN * 0.5)
        done_n = dr.abs(luma_end_n) >= gradient_scaled
        done_p = dr.abs(luma_end_p) >= gradient_scaled
        posNx = dr.select(done_n, posNx, posNx - offx * step)
        posNy = dr.select(done_n, posNy, posNy - offy * step)
        posPx = dr.select(done_p, posPx, posPx + offx * step)
        posPy = dr.select(done_p, posPy, posPy + offy * step)

    # 5. offset from the closer end, or the subpixel offset
    dstN = dr.select(horz, posMx - posNx, posMy - posNy)
    dstP = dr.select(horz, posPx - posMx, posPy - posMy)
    good_span_n = (luma_end_n < 0.0) ^ luma_m_lt_zero
    span_length = dstP + dstN
    good_span_p = (luma_end_p < 0.0) ^ luma_m_lt_zero
    span_length_rcp = 1.0 / span_length
    direction_n = dstN < dstP
    dst = dr.minimum(dstN, dstP)
    good_span = dr.select(direction_n, good_span_n, good_span_p)
    subpixG = subpixF * subpixF
    pixel_offset = dst * (-span_length_rcp) + 0.5
    subpixH = subpixG * p.subpix
    pixel_offset_good = dr.select(good_span, pixel_offset, 0.0)
    offset = dr.maximum(pixel_offset_good, subpixH) * length_sign

    # 6. one bilinear fetch across the edge
    fx = dr.select(horz, posMx, posMx + offset)
    fy = dr.select(horz, posMy + offset, posMy)
    out = dr.clip(K.bilinear(grid, rgb, fx, fy), 0.0, 1.0)
    out = dr.select(early_exit, rgb, out)
    dr.eval(out)
    terms = {"luma": luma, "early_exit": mi.Float(dr.select(early_exit, 1.0, 0.0)),
             "horz_span": mi.Float(dr.select(horz, 1.0, 0.0)),
             "pixel_offset": dr.select(early_exit, 0.0, offset)}
    return out, terms

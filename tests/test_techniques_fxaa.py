"""FXAA 3.11 (quality, preset 39): hand-computed cases, invariants, and a scalar transliteration of
the shader (early return, nested search) as an oracle for the vectorised Dr.Jit version."""
from __future__ import annotations

import numpy as np
import pytest

import backend  # noqa: F401  (before anything touches drjit)

import taa_impl
from display import DisplayTransform
from taa_impl import ENCODED
from taa_impl.fxaa import FXAA_QUALITY_PRESETS, LUMAS

F = np.float32


def fxaa(img, display=ENCODED, **params):
    t = taa_impl.make("fxaa", **params)
    return t.process({"color": np.asarray(img, F)}, jitter=(0, 0), far=1.0, display=display), t


def grey(a):
    return np.repeat(np.asarray(a, F)[..., None], 3, axis=-1)


# ----------------------------------------------------------------------- scalar oracle
def oracle_fxaa(rgb, params):
    """FxaaPixelShader (FXAA_PC, quality) pixel by pixel, float32, written as the shader reads."""
    rgb = np.asarray(rgb, F)
    h, w = rgb.shape[:2]
    luma = (rgb[..., 0] * F(LUMAS[params.luma][0]) + rgb[..., 1] * F(LUMAS[params.luma][1])
            + rgb[..., 2] * F(LUMAS[params.luma][2])).astype(F)
    P = [F(s) for s in FXAA_QUALITY_PRESETS[params.preset]]
    half, two = F(0.5), F(2.0)

    def texel(img, x, y):
        return img[min(max(y, 0), h - 1), min(max(x, 0), w - 1)]

    def tex_top(img, px, py):  # bilinear, clamp-to-edge, texel centres at +0.5
        u = F(min(max(px - half, F(-1)), F(w)))
        v = F(min(max(py - half, F(-1)), F(h)))
        x0, y0 = int(np.floor(u)), int(np.floor(v))
        tx, ty = F(u - F(x0)), F(v - F(y0))
        a, b = texel(img, x0, y0), texel(img, x0 + 1, y0)
        c, d = texel(img, x0, y0 + 1), texel(img, x0 + 1, y0 + 1)
        top, bot = a + (b - a) * tx, c + (d - c) * tx
        return top + (bot - top) * ty

    out = rgb.copy()
    for y in range(h):
        for x in range(w):
            L = lambda dx, dy: texel(luma, x + dx, y + dy)  # noqa: E731
            lumaM, lumaS, lumaE, lumaN, lumaW = L(0, 0), L(0, 1), L(1, 0), L(0, -1), L(-1, 0)
            rangeMax = max(max(lumaN, lumaW), max(lumaE, max(lumaS, lumaM)))
            rangeMin = min(min(lumaN, lumaW), min(lumaE, min(lumaS, lumaM)))
            rng = F(rangeMax - rangeMin)
            if rng < max(F(params.edge_threshold_min), F(rangeMax * F(params.edge_threshold))):
                continue                                           # early exit: return rgbyM
            lumaNW, lumaSE, lumaNE, lumaSW = L(-1, -1), L(1, 1), L(1, -1), L(-1, 1)
            lumaNS, lumaWE = F(lumaN + lumaS), F(lumaW + lumaE)
            subpixRcpRange = F(F(1) / rng)
            subpixNSWE = F(lumaNS + lumaWE)
            edgeHorz1 = F(-two * lumaM + lumaNS)
            edgeVert1 = F(-two * lumaM + lumaWE)
            lumaNESE, lumaNWNE = F(lumaNE + lumaSE), F(lumaNW + lumaNE)
            edgeHorz2 = F(-two * lumaE + lumaNESE)
            edgeVert2 = F(-two * lumaN + lumaNWNE)
            lumaNWSW, lumaSWSE = F(lumaNW + lumaSW), F(lumaSW + lumaSE)
            edgeHorz4 = F(abs(edgeHorz1) * two + abs(edgeHorz2))
            edgeVert4 = F(abs(edgeVert1) * two + abs(edgeVert2))
            edgeHorz3 = F(-two * lumaW + lumaNWSW)
            edgeVert3 = F(-two * lumaS + lumaSWSE)
            edgeHorz = F(abs(edgeHorz3) + edgeHorz4)
            edgeVert = F(abs(edgeVert3) + edgeVert4)
            subpixNWSWNESE = F(lumaNWSW + lumaNESE)
            lengthSign = F(1)
            horzSpan = edgeHorz >= edgeVert
            subpixA = F(subpixNSWE * two + subpixNWSWNESE)
            if not horzSpan:
                lumaN, lumaS = lumaW, lumaE
            subpixB = F(subpixA * F(1.0 / 12.0) - lumaM)
            gradientN, gradientS = F(lumaN - lumaM), F(lumaS - lumaM)
            lumaNN, lumaSS = F(lumaN + lumaM), F(lumaS + lumaM)
            pairN = abs(gradientN) >= abs(gradientS)
            gradient = max(abs(gradientN), abs(gradientS))
            if pairN:
                lengthSign = -lengthSign
            subpixC = F(min(max(abs(subpixB) * subpixRcpRange, F(0)), F(1)))
            posMx, posMy = F(x + 0.5), F(y + 0.5)
            posBx, posBy = posMx, posMy
            offx, offy = (F(1), F(0)) if horzSpan else (F(0), F(1))
            if horzSpan:
                posBy = F(posBy + lengthSign * half)
            else:
                posBx = F(posBx + lengthSign * half)
            posNx, posNy = F(posBx - offx * P[0]), F(posBy - offy * P[0])
            posPx, posPy = F(posBx + offx * P[0]), F(posBy + offy * P[0])
            subpixD = F(-two * subpixC + F(3))
            lumaEndN = tex_top(luma, posNx, posNy)
            subpixE = F(subpixC * subpixC)
            lumaEndP = tex_top(luma, posPx, posPy)
            if not pairN:
                lumaNN = lumaSS
            gradientScaled = F(gradient * F(0.25))
            lumaMM = F(lumaM - lumaNN * half)
            subpixF = F(subpixD * subpixE)
            lumaMLTZero = lumaMM < 0
            lumaEndN = F(lumaEndN - lumaNN * half)
            lumaEndP = F(lumaEndP - lumaNN * half)
            doneN = abs(lumaEndN) >= gradientScaled
            doneP = abs(lumaEndP) >= gradientScaled
            if not doneN:
                posNx, posNy = F(posNx - offx * P[1]), F(posNy - offy * P[1])
            doneNP = (not doneN) or (not doneP)
            if not doneP:
                posPx, posPy = F(posPx + offx * P[1]), F(posPy + offy * P[1])
            for step in P[2:]:                     # the nested `if(doneNP) { ... }` blocks
                if not doneNP:
                    break
                if not doneN:
                    lumaEndN = F(tex_top(luma, posNx, posNy) - lumaNN * half)
                if not doneP:
                    lumaEndP = F(tex_top(luma, posPx, posPy) - lumaNN * half)
                doneN = abs(lumaEndN) >= gradientScaled
                doneP = abs(lumaEndP) >= gradientScaled
                if not doneN:
                    posNx, posNy = F(posNx - offx * step), F(posNy - offy * step)
                doneNP = (not doneN) or (not doneP)
                if not doneP:
                    posPx, posPy = F(posPx + offx * step), F(posPy + offy * step)
            dstN = F(posMx - posNx) if horzSpan else F(posMy - posNy)
            dstP = F(posPx - posMx) if horzSpan else F(posPy - posMy)
            goodSpanN = (lumaEndN < 0) != lumaMLTZero
            spanLength = F(dstP + dstN)
            goodSpanP = (lumaEndP < 0) != lumaMLTZero
            spanLengthRcp = F(F(1) / spanLength)
            directionN = dstN < dstP
            dst = min(dstN, dstP)
            goodSpan = goodSpanN if directionN else goodSpanP
            subpixG = F(subpixF * subpixF)
            pixelOffset = F(dst * -spanLengthRcp + half)
            subpixH = F(subpixG * F(params.subpix))
            pixelOffsetGood = pixelOffset if goodSpan else F(0)
            pixelOffsetSubpix = max(pixelOffsetGood, subpixH)
            if horzSpan:
                posMy = F(posMy + pixelOffsetSubpix * lengthSign)
            else:
                posMx = F(posMx + pixelOffsetSubpix * lengthSign)
            out[y, x] = np.clip(tex_top(rgb, posMx, posMy), 0, 1)
    return out


# ------------------------------------------------------------------------------- params
def test_params_and_presets():
    p = taa_impl.make("fxaa").params
    assert (p.preset, p.subpix, p.edge_threshold, p.edge_threshold_min, p.luma) == \
        (39, 0.75, 0.125, 0.0312, "rec601")
    assert p.steps == (1.0, 1.0, 1.0, 1.0, 1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 4.0, 8.0)
    assert sum(p.steps) == 26.5             # the farthest an edge end can be from the pixel
    assert taa_impl.make("fxaa", edge_threshold=0.063, edge_threshold_min=0.0625).params.edge_threshold == 0.063
    for bad in ({"preset": 40}, {"subpix": 1.5}, {"edge_threshold": 0.0}, {"luma": "rec709"}):
        with pytest.raises(ValueError):
            taa_impl.make("fxaa", **bad)
    t = taa_impl.make("fxaa")
    with pytest.raises(ValueError):          # it works on the display image: needs the transform
        t.process({"color": np.zeros((4, 4, 3), F)}, jitter=(0, 0), far=1.0)


# -------------------------------------------------------------------------- hand cases
def test_flat_image_is_unchanged_exactly():
    rng = np.random.default_rng(0)
    ref = rng.uniform(0, 3, (8, 8, 3))
    dt = DisplayTransform.from_reference(ref)
    img = np.empty((9, 11, 3), F)
    img[:] = (0.3, 1.7, 0.05)
    out, t = fxaa(img, display=dt)
    assert np.array_equal(out, np.broadcast_to(dt.encode(img).astype(F), out.shape))
    assert np.all(t.debug_terms()["early_exit"] == 1)


@pytest.mark.parametrize("a,b", [(0.2, 0.8), (0.9, 0.1)])
def test_horizontal_step_edge_gets_only_the_subpixel_blend(a, b):
    # rows 0..4 colour A, rows 5..9 colour B. Along a straight edge both search ends are at the
    # maximum distance, so the edge offset is 0.5 - 26.5/53 = 0; the rows next to the step have
    # |lowpass - M| / range = 1/3 and move toward each other by subpix * smoothstep(1/3)^2
    # = 0.75 * (7/27)^2 = 0.0504; every other row exits early, unchanged.
    img = grey(np.where(np.arange(10)[:, None] < 5, a, b) * np.ones((1, 12)))
    out, t = fxaa(img)
    s = 0.75 * (7 / 27) ** 2
    np.testing.assert_array_equal(out[:4], img[:4])
    np.testing.assert_array_equal(out[6:], img[6:])
    np.testing.assert_allclose(out[4], a + (b - a) * s, atol=1e-6)
    np.testing.assert_allclose(out[5], b + (a - b) * s, atol=1e-6)
    terms = t.debug_terms()
    assert np.all(terms["horz_span"][4:6] == 1)
    np.testing.assert_allclose(np.abs(terms["pixel_offset"][4:6]), s, atol=1e-6)
    # subpix = 0: a long straight edge is left exactly as it is
    out0, _ = fxaa(img, subpix=0.0)
    np.testing.assert_array_equal(out0, img)
    # the vertical edge is the transpose
    outT, tT = fxaa(img.transpose(1, 0, 2))
    np.testing.assert_allclose(outT, out.transpose(1, 0, 2), atol=1e-7)
    assert np.all(tT.debug_terms()["horz_span"][:, 4:6] == 0)


def test_end_of_a_long_edge_gets_the_gradient_blend():
    # B (0.8) fills rows >= 8 left of x = 32, A (0.2) the rest. On row 8, the last B pixels
    # x = 31 - d see the edge end d + 1 pixels to the right and the other end beyond the search
    # (26.5): offset 0.5 - (d + 1) / (27.5 + d) toward the A row above (good span: the luma at the
    # found end, A, is on the other side of the pair average from M = B).
    a, b = 0.2, 0.8
    img = np.full((16, 64), a, F)
    img[8:, :32] = b
    out, t = fxaa(grey(img))
    off = t.debug_terms()["pixel_offset"]
    for d in range(4):
        x = 31 - d
        want = 0.5 - (d + 1) / (27.5 + d)
        assert off[8, x] == pytest.approx(-want, abs=1e-6), d
        np.testing.assert_allclose(out[8, x], b + (a - b) * want, atol=1e-6)
    # above them (row 7, colour A) the end is not a good span: only the subpixel term acts,
    # 0.75 * smoothstep(1/3)^2 (one B neighbour below), 0.75 * smoothstep(1/4)^2 at x = 31
    assert off[7, 29] == pytest.approx(0.75 * (7 / 27) ** 2, abs=1e-6)
    assert off[7, 31] == pytest.approx(0.75 * ((3 - 0.5) / 16) ** 2, abs=1e-6)
    # far from the end the edge is straight: subpixel term only
    assert abs(off[8, 5]) == pytest.approx(0.75 * (7 / 27) ** 2, abs=1e-6)


def test_diagonal_staircase_is_blended_and_transpose_symmetric():
    n = 14
    ys, xs = np.indices((n, n))
    img = grey(np.where(xs > ys, 0.9, 0.1))         # 45-degree staircase of one-pixel steps
    out, _ = fxaa(img)
    outT, _ = fxaa(img.transpose(1, 0, 2))
    np.testing.assert_allclose(outT, out.transpose(1, 0, 2), atol=1e-6)
    # the pixels on both sides of the steps (x = y: 0.1, x = y + 1: 0.9) are blended; their other
    # neighbours (x = y - 1, x = y + 2) touch the steps only diagonally, and FXAA's early exit
    # looks at N, S, E, W: they stay as they are
    edge = ((xs - ys == 0) | (xs - ys == 1)) & (xs > 0) & (ys < n - 1)   # (off the two corners)
    assert edge.sum() == 2 * (n - 2) + 1
    assert np.all((out[edge] > 0.1 + 1e-3) & (out[edge] < 0.9 - 1e-3))
    rest = (xs - ys != 0) & (xs - ys != 1)
    np.testing.assert_array_equal(out[rest], img[rest])
    # by hand: M = 0.1 at (x, x) sees N, NE, E = 0.9: lowpass = (2 * 2 + 1) / 12 of the range
    # -> subpix 0.75 * smoothstep(5/12)^2 = 0.1060 toward 0.9 (the edge offset is smaller)
    # and M = 0.9 at (x + 1, x) likewise toward 0.1 (the staircase is symmetric under 180-degree
    # rotation with the colours swapped)
    s = 0.75 * ((3 - 2 * 5 / 12) * (5 / 12) ** 2) ** 2
    inner = edge & (ys >= 1) & (xs <= n - 2)       # (at the borders clamp-to-edge changes the 3x3)
    np.testing.assert_allclose(out[inner & (xs == ys)], 0.1 + 0.8 * s, atol=1e-6)
    np.testing.assert_allclose(out[inner & (xs == ys + 1)], 0.9 - 0.8 * s, atol=1e-6)


def test_shallow_staircase_is_blended_along_each_step():
    # a line of slope 1/4 (steps 4 pixels long, 1 pixel high): the pixels along each step get
    # offsets that vary with their distance to the step's ends (FXAA's signature gradient)
    h, w = 12, 40
    ys, xs = np.indices((h, w))
    img = grey(np.where(ys > 2 + xs // 4, 0.85, 0.15))
    out, t = fxaa(img)
    off = np.abs(t.debug_terms()["pixel_offset"])
    assert len(np.unique(np.round(off[off > 0], 4))) >= 3
    changed = np.any(out != img, axis=-1)
    assert changed.sum() > 0 and np.all((out[changed] > 0.15) & (out[changed] < 0.85))
    np.testing.assert_array_equal(out, oracle_fxaa(img, t.params))


def test_green_luma_misses_red_blue_edges():
    img = np.zeros((8, 8, 3), F)
    img[:, :4] = (1, 0, 0)
    img[:, 4:] = (0, 0, 1)
    img[2, 2] = (0, 0, 1)                           # an aliased speck
    out_g, _ = fxaa(img, luma="green")
    np.testing.assert_array_equal(out_g, img)       # no green: nothing to see
    out_l, _ = fxaa(img)                            # Rec.601 luma sees it
    assert not np.array_equal(out_l, img)


# ---------------------------------------------------------------------- invariants, oracle
@pytest.mark.parametrize("seed", [0, 1])
def test_hdr_input_through_the_display_transform_stays_in_range(seed):
    rng = np.random.default_rng(seed)
    ref = rng.lognormal(0, 2, (12, 14, 3)).astype(F)
    dt = DisplayTransform.from_reference(ref)
    img = ref * rng.uniform(0.5, 2, ref.shape).astype(F)
    img[3, 3] = (1e6, 1e6, 1e6)
    out, t = fxaa(img, display=dt)
    assert out.dtype == np.float32 and np.all((out >= 0) & (out <= 1))
    # what it works on is the encoded image, and unchanged pixels are exactly that
    enc = dt.encode(img).astype(F)
    same = t.debug_terms()["early_exit"] == 1
    assert same.any() and np.array_equal(out[same], enc[same])
    np.testing.assert_allclose(out, oracle_fxaa(enc, t.params), atol=2e-6)


@pytest.mark.parametrize("params", [{}, {"subpix": 1.0, "edge_threshold": 0.063, "edge_threshold_min": 0.0625},
                                    {"preset": 12}, {"luma": "green"}])
def test_matches_scalar_oracle(params):
    rng = np.random.default_rng(4)
    h, w = 20, 24
    # blocky 8-bit image: random rectangles over noise, so edges of every orientation and length
    img = np.round(rng.uniform(0.39, 0.41, (h, w, 3)) * 255) / 255
    for _ in range(5):
        x0, y0 = rng.integers(0, w - 3), rng.integers(0, h - 3)
        img[y0:y0 + rng.integers(2, 8), x0:x0 + rng.integers(2, 12)] = np.round(rng.random(3) * 255) / 255
    ys, xs = np.indices((h, w))
    img[np.abs(3 * xs - 7 * ys + 40) < 6] *= 0.5    # a sloped band
    img = img.astype(F)
    out, t = fxaa(img, **params)
    ref = oracle_fxaa(img, t.params)
    np.testing.assert_allclose(out, ref, atol=2e-6)
    assert 0.05 < np.mean(np.any(out != img, axis=-1)) < 0.95   # both paths exercised
    assert np.all((out >= 0) & (out <= 1))


def test_nonfinite_input_is_repaired():
    img = np.full((6, 6, 3), 0.5, F)
    img[2, 3] = np.nan
    out, t = fxaa(img)
    assert np.all(np.isfinite(out)) and t.last_nonfinite_count == 1
    np.testing.assert_array_equal(out, 0.5)


def test_early_exit_is_strict_at_the_threshold():
    # FXAA 3.11: `if (range < max(fxaaQualityEdgeThresholdMin, rangeMax * fxaaQualityEdgeThreshold))`
    # returns the pixel unchanged. In a 0.5 field a centre of 0.4375 has range 0.0625 = 0.5 * 0.125
    # (exact in float32): not below the threshold, so it is processed; 0.4453125 (range 0.0546875) exits.
    for centre, exits in ((0.4375, 0), (0.4453125, 1)):
        img = grey(np.full((7, 7), 0.5))
        img[3, 3] = centre
        out, t = fxaa(img, luma="green")
        assert t.debug_terms()["early_exit"][3, 3] == exits, centre
        assert np.array_equal(out[3, 3], img[3, 3]) == bool(exits), centre

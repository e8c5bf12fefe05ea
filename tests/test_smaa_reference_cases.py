"""SMAA blending weights in the cases where the reference implementation (iryoku/smaa, ULTRA)
differs from a plain revectorisation: short U shapes (smoothed), ends with crossing edges on both
sides (a Z), diagonal runs (its line placements), 1-pixel lines; the reference's tabulation of the
area functions; and the clamp-to-edge read of the weights in the blending pass.

Hand values are derived in each docstring. Coordinates: pixel (x, y), y down; a pixel's top-edge
weights are r (it takes from the pixel above) and g (the pixel above takes from it)."""
from __future__ import annotations

import numpy as np
import pytest

import backend  # noqa: F401  (before anything touches drjit)
from backend import dr, mi

import taa_impl
from taa_impl import ENCODED
from taa_impl import kernels as K
from taa_impl import smaa_area as A
from taa_impl.smaa import SMAAParams, neighbourhood_blend

F = np.float32


def smaa(img, **params):
    t = taa_impl.make("smaa", **params)
    out = t.process({"color": np.asarray(img, F)}, jitter=(0, 0), far=1.0, display=ENCODED)
    return out, t.debug_terms()


def grey(a):
    return np.repeat(np.asarray(a, F)[..., None], 3, axis=-1)


def smooth(a, d):
    """The U smoothing of one half's area, by its definition."""
    b = np.sqrt(2 * a) / 2
    return b + (a - b) * min(d / 32, 1.0)


def byte(a):
    return np.floor(255 * a) / 255


# ------------------------------------------------------------------------------ short U
def test_short_u_is_smoothed():
    """White below row 10, plus a bump: row 9 is white for x = 10..15. The bump's top edge (row 9,
    d = 6) bends down at both ends (left edges of (10, 9) and (16, 9), on the line's own row:
    code 3 at both ends): a U. Its revectorised halves fall from -1/2 at the ends to 0 at the
    middle t = 3: pixel x covers t in [x - 10, x - 9], area A = mean |h|:
      x = 10: (1/2 + 1/3) / 2 = 5/12,   x = 11: (1/3 + 1/6) / 2 = 1/4,   x = 12: (1/6 + 0) / 2 = 1/12
    (mirrored for x = 13..15). Smoothed with k = d / 32 = 3/16: A -> b + (A - b) k, b = sqrt(2 A)/2:
      x = 10: b = 0.456435 -> 0.448979;  x = 11: b = 0.353553 -> 0.334138;
      x = 12: b = 0.204124 -> 0.181476.
    No corner rounding: the crossing edges do not continue into rows 10 or 7.
    Reference tabulation: x = 11 has distances (1, 4), both perfect squares, so the texture holds
    its value exactly, as a byte: floor(255 * 0.334138) = 85 -> 85/255; likewise x = 14 (4, 1)."""
    img = np.zeros((20, 28), F)
    img[10:] = 1.0
    img[9, 10:16] = 1.0
    _, t = smaa(grey(img), area="exact")
    r, g = t["weight_r"][9], t["weight_g"][9]
    hand = {10: 0.448979, 11: 0.334138, 12: 0.181476}
    for x, v in hand.items():
        assert r[x] == pytest.approx(v, abs=2e-6)
        assert r[25 - x] == pytest.approx(v, abs=2e-6)       # x = 15, 14, 13
        assert r[x] == pytest.approx(smooth([5 / 12, 1 / 4, 1 / 12][x - 10], 6), abs=1e-6)
    assert not g[10:16].any()
    _, t = smaa(grey(img))
    assert t["weight_r"][9, 11] == pytest.approx(85 / 255, abs=1e-7)
    assert t["weight_r"][9, 14] == pytest.approx(85 / 255, abs=1e-7)
    # the unsmoothed triangle would blend visibly less: 1/4 against 0.334
    assert t["weight_r"][9, 11] > 0.25 + 0.08


# ------------------------------------------------------------------------------ Z with a '+' end
@pytest.mark.parametrize("mirror", [False, True])
def test_z_with_crossing_edges_on_both_sides_of_an_end(mirror):
    """Black above, white below; the boundary is row 11 for x < 8 and row 10 for 8 <= x < 24;
    columns x >= 24 are grey (0.5). The row-10 segment x = 8..23 (d = 16) has at its left end a
    crossing edge below the line (left edge of (8, 10): code 3) and at its right end crossing edges
    on both sides (the grey columns' left edges in rows 9 and 10: code 4). The '+' end takes the
    bend opposite to the other end's, so the segment is a full Z: the line h(t) = -1/2 + t / 16
    over t in [0, 16], pixel x covering [x - 8, x - 7]:
      r = (15.5 - x) / 16 for x = 8..15,  g = (x - 15.5) / 16 for x = 16..23.
    The grey edge continues into rows 11 and 8, a corner: the weights of the pixels nearer that
    end (x >= 16) are scaled by corner_rounding / 100 = 1/4: g = (x - 15.5) / 64. (The left end's
    crossing edge does not continue: no rounding there.) Mirrored left-right, the '+' end is on
    the left and the weights are mirrored."""
    w = 32
    img = np.zeros((20, w), F)
    for x in range(24):
        img[11 if x < 8 else 10:, x] = 1.0
    img[:, 24:] = 0.5
    xs = np.arange(8, 24)
    if mirror:
        img = img[:, ::-1].copy()
    _, t = smaa(grey(img), area="exact")
    r, g = t["weight_r"][10], t["weight_g"][10]
    if mirror:
        r, g = r[::-1], g[::-1]
    np.testing.assert_allclose(r[8:24], np.where(xs <= 15, (15.5 - xs) / 16, 0), atol=1e-6)
    np.testing.assert_allclose(g[8:24], np.where(xs >= 16, (xs - 15.5) / 64, 0), atol=1e-6)
    assert r[8] == pytest.approx(0.46875, abs=1e-6) and g[23] == pytest.approx(0.46875 / 4, abs=1e-6)


# ------------------------------------------------------------------------------ diagonal staircase
@pytest.mark.parametrize("mirror", [False, True])
def test_diagonal_staircase_from_a_vertical_into_a_flat(mirror):
    """Column boundary (white below row top(x)): top(x) = 32 (all black) for x < 8, 36 - x for
    x = 8..20, 16 for x > 20. The pixels (x, 36 - x), x = 8..20, have a left and a top edge: a '/'
    run. Below its bottom end the edge goes on vertically (left edges of (8, 29..31)): crossing
    code 1 (the end pixel (8, 28) has its own left edge, (7, 28) no top edge); past its top end it
    goes on horizontally ((21, 16) has a top edge, (21, 15) no left edge): code 2. A vertical
    continuation below and a horizontal one above put both ends of the line on the inner corners:
    the line is the 45-degree line through the staircase's inner corners, which cuts every step
    pixel in half and misses the pixel above it: r = 1/2, g = 0 for every pixel of the run (so a
    white step pixel becomes mid grey and the black pixel above stays black).
    Reference tabulation: the pixel's lattice has 435 points strictly below the line, 435 above
    and 30 on it, which the reference's float64 test puts on either side depending on rounding:
    r = 1 - (count below) / 900 in [1 - 465/900, 1 - 435/900], stored as a byte.
    Mirrored left-right it is a '\\' run (top and right edges), which the reference looks up in the
    '/' frame flipped vertically with r and g swapped: the same weights at the mirrored pixels.
    (Not the same output: there the steps' vertical edges are the left edges of the black pixels
    beside them, which have no top edge, so the reference treats them as 1-pixel vertical
    segments.)"""
    h = w = 32
    xs = np.arange(8, 21)
    top = lambda x: 32 if x < 8 else (36 - x if x <= 20 else 16)  # noqa: E731
    img = np.zeros((h, w), F)
    for x in range(w):
        img[top(x):, x] = 1.0
    px = (w - 1 - xs) if mirror else xs
    if mirror:
        img = img[:, ::-1].copy()
    out, t = smaa(grey(img), area="exact", blend_space="display")
    ys = 36 - xs
    assert t["diagonal"][ys, px].all()
    np.testing.assert_allclose(t["weight_r"][ys, px], 0.5, atol=1e-7)
    np.testing.assert_allclose(t["weight_g"][ys, px], 0.0, atol=1e-7)
    if not mirror:
        np.testing.assert_allclose(out[ys, px], 0.5, atol=1e-6)
        np.testing.assert_array_equal(out[ys - 1, px], 0.0)
    _, t = smaa(grey(img))
    r = t["weight_r"][ys, px]
    assert np.all((r >= byte(1 - 465 / 900) - 1e-7) & (r <= byte(1 - 435 / 900) + 1e-7))
    np.testing.assert_allclose(r * 255, np.round(r * 255), atol=1e-4)   # bytes
    assert not t["weight_g"][ys, px].any()


# ------------------------------------------------------------------------------ 1-pixel line
def test_one_pixel_line():
    """A white line one pixel wide on black: row 10 for x = 4..19, row 9 for x = 20..35.
    Its top side in row 10 (the top edges of (x, 10), x = 4..19, d = 16): the left end bends down
    (left edge of (4, 10), code 3); at the right end the line steps up, so both rows carry a
    crossing edge (left edges of (20, 9) and (20, 10): code 4) and the end mirrors the left one:
    a Z, h(t) = -1/2 + t / 16 with t = x - 4:
      r = (7.5 - t) / 16 for t = 0..7,  g = (t - 7.5) / 16 for t = 8..15 (no corners).
    Its bottom side (the top edges of (x, 11), x = 4..19): both ends bend up (left edges of (4, 10)
    and (20, 10), above the line: code 1): a U of d = 16 above the edge, so the line pixels take g
    from below. Each half's triangle area A = |t + 1/2 - 8| / 16 is smoothed with k = 16/32:
    (A + sqrt(2 A) / 2) / 2, e.g. t = 0: (0.46875 + 0.484123) / 2 = 0.476436, t = 7:
    (0.03125 + 0.125) / 2 = 0.078125. At the right end the crossing edge continues up (left edge
    of (20, 9)), a corner for the g side: for t >= 8 (nearer that end) g is scaled by 1/4:
    t = 8: 0.078125 / 4, t = 15: 0.476436 / 4."""
    img = np.zeros((20, 40), F)
    img[10, 4:20] = 1.0
    img[9, 20:36] = 1.0
    _, t = smaa(grey(img), area="exact")
    tt = np.arange(16)
    r10, g10 = t["weight_r"][10, 4:20], t["weight_g"][10, 4:20]
    np.testing.assert_allclose(r10, np.where(tt <= 7, (7.5 - tt) / 16, 0), atol=1e-6)
    np.testing.assert_allclose(g10, np.where(tt >= 8, (tt - 7.5) / 16, 0), atol=1e-6)
    g11 = t["weight_g"][11, 4:20]
    a = np.where(tt <= 7, 7.5 - tt, tt - 7.5) / 16
    hand = (a + np.sqrt(2 * a) / 2) / 2 * np.where(tt >= 8, 0.25, 1.0)
    np.testing.assert_allclose(g11, hand, atol=2e-6)
    assert g11[0] == pytest.approx(0.476436, abs=1e-6) and g11[7] == pytest.approx(0.078125)
    assert g11[8] == pytest.approx(0.078125 / 4) and g11[15] == pytest.approx(0.476436 / 4, abs=1e-6)
    assert not t["weight_r"][11, 4:20].any()


def test_one_pixel_line_end_reference_tabulation():
    """The same construction with a 10-pixel lower part (row 10, x = 4..13; row 9, x = 14..29):
    the top side of row 10 is a Z of d = 10; its first pixel has distances (0, 9), both perfect
    squares, so the texture holds the exact area (h from -1/2 to -0.4: r = 0.45) as the byte
    floor(114.75) = 114. Pixel x = 5 has distances (1, 8): between the texels (1, 4) and (1, 9)
    at sqrt(8) = 2.828427, bilinearly: Z d = 6 at t in [1, 2]: h from -1/3 to -1/6, 0.25 ->
    byte 63; Z d = 11: h from -0.5 + 1/11 to -0.5 + 2/11, 0.363636 -> byte 92; so
    r = (63 + (92 - 63) * 0.828427) / 255 = 0.341271 (the exact value is 0.5 - 1.5/10 = 0.35)."""
    img = np.zeros((20, 40), F)
    img[10, 4:14] = 1.0
    img[9, 14:30] = 1.0
    _, t = smaa(grey(img))
    assert t["weight_r"][10, 4] == pytest.approx(114 / 255, abs=1e-7)
    assert t["weight_r"][10, 5] == pytest.approx((63 + 29 * (np.sqrt(8) - 2)) / 255, abs=1e-6)
    _, te = smaa(grey(img), area="exact")
    assert te["weight_r"][10, 4] == pytest.approx(0.45, abs=1e-6)
    assert te["weight_r"][10, 5] == pytest.approx(0.35, abs=1e-6)


# ------------------------------------------------------------------------------ tabulation
def test_reference_tables_are_bytes_of_the_area_functions():
    """The orthogonal table holds floor(255 a) / 255 of the exact area function at squared
    distances; the diagonal one the lattice-sampled areas as bytes, within the sampling error of
    the exact ones (a line crosses at most 30 lattice columns and rows: |error| <= 1/30 plus the
    truncation)."""
    o = A.ortho_table()
    assert o.shape == (5, 5, 16, 16, 2)
    np.testing.assert_allclose(o * 255, np.round(o * 255), atol=1e-4)
    i, j = np.meshgrid(np.arange(16.0), np.arange(16.0), indexing="ij")
    for c1, c2 in ((3, 1), (1, 1), (3, 0), (4, 1), (1, 4), (4, 4), (4, 0)):
        r, g = A.ortho_area(i * i, j * j, np.full_like(i, c1), np.full_like(i, c2), A.NP)
        for tab, exact in ((o[c1, c2, ..., 0], r), (o[c1, c2, ..., 1], g)):   # float32 bytes
            assert np.all((tab <= exact + 1e-7) & (tab > exact - 1 / 255 - 1e-7))
    assert not o[4, 4].any() and not o[4, 0].any() and not o[0, 0].any()   # no bend to revectorise
    # hand entries: L from below at distances (0, 0): d = 1, the triangle under [0, 1/2]: 1/8
    assert o[3, 0, 0, 0, 0] == pytest.approx(byte(0.125)) and o[3, 0, 0, 0, 1] == 0
    # U above at distances (1, 4) (the short-U case, d = 6): 0.334138 -> byte 85 in g
    assert o[1, 1, 1, 2, 1] == pytest.approx(85 / 255)
    d, e = A.diag_table("reference"), A.diag_table("exact")
    used = np.add.outer(np.arange(20), np.arange(20)) >= 3
    assert np.abs(d - e)[:, :, used].max() < 1 / 30 + 1 / 255
    assert e[0, 0][used].min() == e[0, 0][used].max() == 0.25


def test_areas_match_a_numeric_integration_of_the_revectorised_line():
    """Dr.Jit's exact orthogonal area (float32) against midpoint integration in float64, over all
    end codes and a grid of distances, smoothing included."""
    codes = (0, 1, 3, 4)
    dl, dright, c1, c2 = (v.ravel() for v in np.meshgrid(np.arange(0, 40, 3.0), np.arange(0, 40, 5.0),
                                                         codes, codes, indexing="ij"))
    r, g = A.ortho_area(mi.Float(dl), mi.Float(dright), mi.Float(c1), mi.Float(c2))
    r, g = np.asarray(r), np.asarray(g)
    n = 20000
    for k in range(len(dl)):
        h1, h2, u = (np.asarray(v) for v in A.ortho_heights(np.float64(c1[k]), np.float64(c2[k]), A.NP))
        d = dl[k] + dright[k] + 1
        m = d / 2
        tt = dl[k] + (np.arange(n) + 0.5) / n
        hh = np.where(tt <= m, h1 * (m - tt) / m, h2 * (tt - m) / m)
        want = [0.0, 0.0]
        for half in (tt <= m, tt > m):
            for s, part in enumerate((np.maximum(-hh, 0), np.maximum(hh, 0))):
                a = part[half].sum() / n
                want[s] += smooth(a, d) if u else a
        assert r[k] == pytest.approx(want[0], abs=3e-6) and g[k] == pytest.approx(want[1], abs=3e-6)


# ------------------------------------------------------------------------------ blending border
@pytest.mark.parametrize("blend_space", ["display", "linear"])
def test_blending_reads_the_weights_clamp_to_edge_at_the_bottom_row_and_last_column(blend_space):
    """4 x 3 image, rows 0..2 of grey levels 0.2, 0.5, 0.8. Bottom-row pixel (1, 2): own g = 0.5,
    own r = 0.3. The reference reads the bottom neighbour's g clamp-to-edge, i.e. its own 0.5:
    vertical blend, w1 = 0.5 / 0.8 towards below (clamped: its own colour), w2 = 0.3 / 0.8 towards
    above at 0.3 px: c2 = 0.7 * 0.8 + 0.3 * 0.5 = 0.71; out = 0.625 * 0.8 + 0.375 * 0.71 = 0.76625
    (in display space; with linear blending the same mix of the decoded values). Reading 0 there
    would give 0.71. Last-column pixel (3, 0): own a = 0.4, own b = 0.2, no vertical weights:
    horizontal, its own 0.4 towards the right (its own colour) and 0.2 towards the left (same
    colour: the row is flat): unchanged."""
    h, w = 3, 4
    rgb = grey(np.repeat(np.array([0.2, 0.5, 0.8], F)[:, None], w, 1))
    R, G, B, Aw = (np.zeros((h, w), F) for _ in range(4))
    G[2, 1], R[2, 1] = 0.5, 0.3
    Aw[0, 3], B[0, 3] = 0.4, 0.2
    out = neighbourhood_blend(K.Grid(w, h), dr.unravel(mi.Color3f, mi.Float(rgb.reshape(-1))),
                              tuple(mi.Float(a.reshape(-1)) for a in (R, G, B, Aw)),
                              SMAAParams(blend_space=blend_space))
    out = np.asarray(dr.ravel(out), F).reshape(h, w, 3)
    if blend_space == "display":
        assert out[2, 1, 0] == pytest.approx(0.625 * 0.8 + 0.375 * 0.71, abs=1e-6)
    else:
        dec = lambda c: ((c + 0.055) / 1.055) ** 2.4  # noqa: E731  (all values here > 0.04045)
        lin = 0.625 * dec(0.8) + 0.375 * (0.7 * dec(0.8) + 0.3 * dec(0.5))
        assert out[2, 1, 0] == pytest.approx(1.055 * lin ** (1 / 2.4) - 0.055, abs=2e-6)
    assert out[0, 3, 0] == pytest.approx(0.2, abs=1e-6)

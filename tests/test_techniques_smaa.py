"""SMAA 1x (ULTRA preset): hand-computed area values for orthogonal and diagonal patterns, corner
rounding, the search function, invariants (flat images, range, transpose symmetry, long straight
edges), a scalar oracle of the orthogonal blending-weight pass and a NumPy oracle of the
neighbourhood blending pass. Hand values of the exact area functions use area='exact'; the
reference's tabulation (the default) is checked here where it is exact (perfect squares, long
runs) and in tests/test_smaa_reference_cases.py."""
from __future__ import annotations

import numpy as np
import pytest

import backend  # noqa: F401  (before anything touches drjit)
from backend import dr, mi

import taa_impl
from display import DisplayTransform
from taa_impl import ENCODED
from taa_impl import kernels as K
from taa_impl.smaa import SMAA_PRESETS, SMAAParams, neighbourhood_blend
from taa_impl.smaa_area import SEARCH_TABLE, search_delta

F = np.float32


def smaa(img, display=ENCODED, **params):
    t = taa_impl.make("smaa", **params)
    out = t.process({"color": np.asarray(img, F)}, jitter=(0, 0), far=1.0, display=display)
    return out, t.debug_terms()


def grey(a):
    return np.repeat(np.asarray(a, F)[..., None], 3, axis=-1)


def srgb_encode(lin):
    lin = np.asarray(lin, np.float64)
    return np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)


def srgb_decode(c):
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def boundary_image(h, w, top_row):
    """White (1) below a per-column boundary, black (0) above: pixel (x, y) is white iff
    y >= top_row(x)."""
    img = np.zeros((h, w), F)
    for x in range(w):
        img[top_row(x):, x] = 1.0
    return grey(img)


# ------------------------------------------------------------------------------ params
def test_registry_params_and_presets():
    t = taa_impl.make("smaa")
    assert (t.name, t.sampling, t.output_space, t.needs) == ("smaa", "centre", "display", {"color"})
    p = t.params
    # SMAA_PRESET_ULTRA + the reference's local contrast adaptation factor
    assert (p.threshold, p.max_search_steps, p.max_search_steps_diag, p.corner_rounding,
            p.local_contrast_adaptation) == (0.05, 32, 16, 25.0, 2.0)
    assert (p.luma, p.blend_space, p.area) == ("rec709", "linear", "reference")
    assert SMAA_PRESETS["ultra"] == dict(threshold=0.05, max_search_steps=32,
                                         max_search_steps_diag=16, corner_rounding=25.0)
    assert taa_impl.make("smaa", **SMAA_PRESETS["high"]).params.max_search_steps == 16
    assert hash(p) == hash(taa_impl.make("smaa").params)
    for bad in (dict(threshold=0.0), dict(max_search_steps=0), dict(max_search_steps_diag=-1),
                dict(max_search_steps=2.5), dict(corner_rounding=101), dict(luma="green"),
                dict(blend_space="hdr"), dict(local_contrast_adaptation=0.0), dict(area="texture"),
                dict(max_search_steps=113), dict(max_search_steps_diag=21)):
        with pytest.raises(ValueError):
            SMAAParams(**bad)
    # beyond the reference's area texture only the exact area functions apply
    assert SMAAParams(max_search_steps=200, max_search_steps_diag=30, area="exact").max_search_steps == 200
    with pytest.raises(ValueError):   # a 'display' technique needs the display transform
        t.process({"color": np.zeros((4, 4, 3), F)}, jitter=(0, 0), far=1.0)


# ------------------------------------------------------------------------------ invariants
@pytest.mark.parametrize("blend_space", ["linear", "display"])
def test_flat_and_sub_threshold_images_are_unchanged_exactly(blend_space):
    flat = np.broadcast_to(np.array([0.2, 0.5, 0.9], F), (9, 13, 3)).copy()
    out, terms = smaa(flat, blend_space=blend_space)
    assert out.dtype == F and out.shape == flat.shape and np.array_equal(out, flat)
    assert not terms["edge_left"].any() and not terms["edge_top"].any()
    # a ramp whose luma steps by 0.04 < threshold 0.05: no edges either
    ramp = grey(np.tile(np.arange(13, dtype=F) * 0.04, (9, 1)))
    out, terms = smaa(ramp, blend_space=blend_space)
    assert np.array_equal(out, ramp) and not terms["edge_left"].any()
    # through a real display transform (HDR constant image): still exactly the encoded image
    hdr = np.full((6, 7, 3), 3.7, F)
    dt = DisplayTransform.from_reference(hdr)
    out, _ = smaa(hdr, display=dt)
    assert np.array_equal(out, dt.encode(hdr).astype(F))


def test_edge_detection_threshold_luma_and_local_contrast():
    # luma steps along a row: 0 | 0.06 | 1.0 | 1.0 ...: the 0 -> 0.06 edge passes the threshold
    # (0.06 >= 0.05) but its right neighbour's delta 0.94 is more than 2x larger: discarded by the
    # local contrast adaptation (SMAA_LOCAL_CONTRAST_ADAPTATION_FACTOR = 2).
    row = np.array([0, 0, 0.06, 1, 1, 1], F)
    _, t = smaa(grey(np.tile(row, (4, 1))))
    assert t["edge_left"][1].tolist() == [0, 0, 0, 1, 0, 0]
    _, t = smaa(grey(np.tile(row, (4, 1))), local_contrast_adaptation=100.0)
    assert t["edge_left"][1].tolist() == [0, 0, 1, 1, 0, 0]
    # luma weights on the encoded values: pure blue 0.5 vs black is 0.0361 in Rec.709 luma (no
    # edge), 0.057 in Rec.601 (an edge)
    img = np.zeros((4, 6, 3), F)
    img[:, 3:, 2] = 0.5
    assert not smaa(img)[1]["edge_left"].any()
    assert smaa(img, luma="rec601")[1]["edge_left"][:, 3].all()


@pytest.mark.parametrize("seed", [0, 1])
def test_output_stays_in_range_for_hdr_and_noise(seed):
    rng = np.random.default_rng(seed)
    hdr = (rng.lognormal(0.0, 2.0, (17, 19, 3)) * (rng.random((17, 19, 1)) < 0.5)).astype(F)
    dt = DisplayTransform.from_reference(hdr)
    for blend_space in ("linear", "display"):
        out, _ = smaa(hdr, display=dt, blend_space=blend_space)
        assert out.dtype == F and np.all(np.isfinite(out)) and out.min() >= 0 and out.max() <= 1
        out, _ = smaa(rng.random((17, 19, 3)).astype(F), blend_space=blend_space)
        assert out.min() >= 0 and out.max() <= 1


# ------------------------------------------------------------------------------ search function
def test_search_table_hand_cases():
    # bits (near, far, near beyond the line, far beyond): fetched value in 1/32 = 21, 7, 3, 1
    assert search_delta(0, (1, 1, 0, 0), (0, 0, 0, 0)) == 2   # both pixels continue the line
    assert search_delta(0, (1, 0, 1, 1), (0, 0, 0, 0)) == 1   # far has no edge (other row ignored)
    assert search_delta(0, (1, 1, 0, 0), (1, 0, 0, 0)) == 1   # crossing edge between near and far
    assert search_delta(0, (1, 1, 0, 0), (0, 1, 0, 0)) == 2   # crossing beyond far: far is the end
    assert search_delta(0, (0, 1, 0, 0), (0, 0, 0, 0)) == 0   # near has no edge: ends before it
    assert search_delta(1, (1, 1, 0, 0), (1, 0, 0, 0)) == 0   # +along: crossing before near
    assert search_delta(1, (1, 1, 0, 0), (0, 0, 0, 1)) == 1   # +along: crossing between near, far
    assert search_delta(1, (1, 1, 0, 0), (0, 0, 0, 0)) == 2
    # the table is indexed by the bilinear values: round(32 * (21 a + 7 b + 3 c + d) / 32)
    assert SEARCH_TABLE.shape == (2, 33, 33)
    assert SEARCH_TABLE[0, 0, 28] == 2 and SEARCH_TABLE[0, 21, 28] == 1 and SEARCH_TABLE[1, 1, 28] == 1


# ------------------------------------------------------------------------------ orthogonal areas
@pytest.mark.parametrize("blend_space", ["display", "linear"])
def test_z_pattern_gets_the_revectorised_line_areas(blend_space):
    """Boundary at row 11 for x < 8, row 10 for 8 <= x < 24, row 9 for x >= 24 (white below):
    the row-10 segment x = 8..23 (d = 16 pixels) has a crossing edge below the line at its left end
    (left edge of pixel (8, 10): code 3) and one above at its right end (left edge of (24, 9):
    code 1). Revectorised line: from height -1/2 at t = 0 (middle of the left crossing edge)
    through 0 at the segment's middle t = 8 to +1/2 at t = 16, i.e. h(t) = -1/2 + t / 16 (h > 0:
    above the edge). Pixel x covers t in [x - 8, x - 7]; its weights are the mean of |h| over that
    interval: r (the pixel takes from the one above) where h < 0, g (the pixel above takes from
    it) where h > 0:
      x = 8:  h from -0.5    to -0.4375 -> r = 0.46875
      x = 9:  h from -0.4375 to -0.375  -> r = 0.40625
      x = 15: h from -0.0625 to  0      -> r = 0.03125
      x = 16: h from  0      to  0.0625 -> g = 0.03125
      x = 23: h from  0.4375 to  0.5    -> g = 0.46875
    i.e. r = (15.5 - x) / 16 for x <= 15, g = (x - 15.5) / 16 for x >= 16. No corner rounding: the
    crossing edges do not continue (pixels (8, 11) / (24, 8) have no left edge)."""
    img = boundary_image(16, 40, lambda x: 11 if x < 8 else (10 if x < 24 else 9))
    out, t = smaa(img, blend_space=blend_space, area="exact")
    r, g = t["weight_r"][10], t["weight_g"][10]
    assert r[8] == pytest.approx(0.46875, abs=1e-6) and r[9] == pytest.approx(0.40625, abs=1e-6)
    assert r[15] == pytest.approx(0.03125, abs=1e-6) and g[16] == pytest.approx(0.03125, abs=1e-6)
    assert g[23] == pytest.approx(0.46875, abs=1e-6)
    xs = np.arange(8, 24)
    np.testing.assert_allclose(r[8:24], np.where(xs <= 15, (15.5 - xs) / 16, 0), atol=1e-6)
    np.testing.assert_allclose(g[8:24], np.where(xs >= 16, (xs - 15.5) / 16, 0), atol=1e-6)
    assert not t["diagonal"].any()
    # blending: white pixel (x, 10), x <= 15, mixes r of the black pixel above; black pixel
    # (x, 9), x >= 16, mixes g of the white one below (1 - w of white, resp. w of white)
    enc = (lambda v: srgb_encode(v)) if blend_space == "linear" else (lambda v: v)
    np.testing.assert_allclose(out[10, 9:16, 0], enc(1 - (15.5 - np.arange(9, 16)) / 16), atol=2e-6)
    np.testing.assert_allclose(out[9, 16:24, 1], enc((np.arange(16, 24) - 15.5) / 16), atol=2e-6)


def test_long_edge_with_one_pixel_step_uses_the_capped_search_distance():
    """Boundary at row 10 for x < 80 and row 9 for x >= 80 (one one-pixel step, two segments of 80
    pixels reaching the image borders). With SMAA_MAX_SEARCH_STEPS = 32 the searches reach 63 px
    to the left (32 fetches of 2 px, the first one covering the pixel itself) and 64 px to the
    right; beyond that the segment counts as ending without a crossing edge (height 0).
    Left segment, pixel (x, 10), 17 <= x <= 79: dl = 63 (capped, no crossing), dr = 79 - x with
    the crossing edge above at the step (code 1): L shape, d = 63 + dr + 1 = 143 - x, middle
    m = d / 2; the line rises from 0 at m to +1/2 at d; the pixel covers t in [63, 64] (right of m
    for x >= 17), so g = 0.5 * (63.5 - m) / m:
      x = 79: m = 32   -> g = 0.5 * 31.5 / 32   = 0.4921875
      x = 78: m = 32.5 -> g = 0.5 * 31   / 32.5 = 0.476923...
      x = 48: m = 47.5 -> g = 0.5 * 16   / 47.5 = 0.168421...
    Right segment, pixel (x, 9), x >= 80: dl = x - 80 with the crossing edge below (the left edge
    of (80, 9) is in the line's own row: code 3), dr = 64 (capped): the line falls from -1/2 at
    t = 0 to 0 at m = (x - 80 + 65) / 2; the pixel covers [x - 80, x - 79], r = 0.5 (m - t_mid) / m:
      x = 80: m = 32.5 -> r = 0.5 * 32   / 32.5 = 0.492307...
      x = 81: m = 33   -> r = 0.5 * 31.5 / 33   = 0.477272...
    A one-pixel step is not a corner (the crossing edge does not continue into rows 8 or 11), so
    corner rounding leaves these weights alone."""
    img = boundary_image(16, 160, lambda x: 10 if x < 80 else 9)
    out, t = smaa(img, blend_space="display", area="exact")
    g10, r9 = t["weight_g"][10], t["weight_r"][9]
    assert g10[79] == pytest.approx(0.4921875, abs=1e-6)
    assert g10[78] == pytest.approx(0.5 * 31 / 32.5, abs=1e-6)
    assert g10[48] == pytest.approx(0.5 * 16 / 47.5, abs=1e-6)
    xs = np.arange(17, 80)
    m = (143 - xs) / 2
    np.testing.assert_allclose(g10[17:80], 0.5 * (63.5 - m) / m, atol=1e-6)
    assert not t["weight_r"][10, 17:80].any()
    assert r9[80] == pytest.approx(0.5 * 32 / 32.5, abs=1e-6)
    assert r9[81] == pytest.approx(0.5 * 31.5 / 33, abs=1e-6)
    # blended: black (79, 9) takes g from below, white (80, 9) takes r from above
    assert out[9, 79, 0] == pytest.approx(0.4921875, abs=1e-6)
    assert out[9, 80, 0] == pytest.approx(1 - 0.5 * 32 / 32.5, abs=1e-6)
    # far from the step (more than 64 px) nothing happens
    assert np.array_equal(out[:, 150:], img[:, 150:])


def test_corner_rounding_keeps_25_percent_at_square_corners():
    """White square rows/cols 8..23 on black. Its top edge (row 8, x = 8..23, d = 16) has crossing
    edges below the line at both ends: U shape, the line falls from -1/2 at both ends to 0 in the
    middle; A = 0.5 * (8 - t_mid) / 8 on the left half: x = 8 -> 0.46875, x = 15 -> 0.03125.
    A U shorter than 32 is smoothed: A -> lerp(sqrt(2 A) / 2, A, 16 / 32) = (A + sqrt(2 A) / 2) / 2:
      x = 8:  (0.46875 + sqrt(0.9375) / 2) / 2 = 0.4764364...
      x = 15: (0.03125 + sqrt(0.0625) / 2) / 2 = (0.03125 + 0.125) / 2 = 0.078125
    The crossing edges continue downwards (the square's sides), so the weights on that side are
    scaled by corner_rounding / 100 = 0.25 at the nearer end. With corner_rounding = 100 corner
    detection is off."""
    img = grey(np.pad(np.ones((16, 16), F), 8))
    a8 = (0.46875 + np.sqrt(0.9375) / 2) / 2
    _, t = smaa(img, area="exact")
    assert t["weight_r"][8, 8] == pytest.approx(a8 * 0.25, abs=1e-7)
    assert t["weight_r"][8, 15] == pytest.approx(0.078125 * 0.25, abs=1e-7)
    assert t["weight_r"][8, 16] == pytest.approx(0.078125 * 0.25, abs=1e-7)
    assert t["weight_b"][8, 8] == pytest.approx(a8 * 0.25, abs=1e-7)   # the left side too
    _, t = smaa(img, corner_rounding=100, area="exact")
    assert t["weight_r"][8, 8] == pytest.approx(a8, abs=1e-7)
    assert t["weight_r"][8, 15] == pytest.approx(0.078125, abs=1e-7)


def test_long_vertical_edge_is_unchanged_far_from_its_ends():
    """White x >= 4 for rows 20..179 of a 200 x 8 image. A pixel on the vertical edge more than
    63 rows below the top end and more than 64 rows above the bottom end sees no crossing edge
    within the search range at either end: pattern 0, area 0 (the paper's prediction: a straight
    edge is not blended). Row 115 finds the bottom end exactly at the 64 px limit, but it lies in
    the upper half of the searched segment (dl = 63 capped, dr = 64, middle at t = 64 = the
    pixel's lower side), whose upper end has no crossing edge: area 0 too. So rows 84..115 come
    out bit-exactly as they went in. Closer to an end it is an L shape (with corner rounding):
    pixel (4, 21): top end 1 px away with the crossing edge on the right side (the top edge of the
    white block, code 3), bottom end capped at 64: d = 66, m = 33, the line is at -1/2 (towards
    the right) at t = 0: b = 0.5 * (33 - 1.5) / 33, times 0.25 (the crossing edge continues: a
    corner)."""
    img = np.zeros((200, 8), F)
    img[20:180, 4:] = 1.0
    img = grey(img)
    for area in ("exact", "reference"):
        out, t = smaa(img, blend_space="display", area=area)
        assert np.array_equal(out[84:116], img[84:116])
        b = t["weight_b"][:, 4]
        assert not b[84:116].any() and not t["weight_a"][84:116].any()
        assert (b[21:84] > 0).all() and (b[116:179] > 0).all()
        assert not np.array_equal(out[21:84], img[21:84])
    _, t = smaa(img, blend_space="display", area="exact")
    assert t["weight_b"][21, 4] == pytest.approx(0.5 * 31.5 / 33 * 0.25, abs=1e-7)


# ------------------------------------------------------------------------------ diagonal areas
@pytest.mark.parametrize("blend_space, area, r, g", [("display", "exact", 0.25, 0.25),
                                                     ("linear", "exact", 0.25, 0.25),
                                                     ("display", "reference", 66 / 255, 61 / 255)])
def test_45_degree_staircase_gets_the_diagonal_area(blend_space, area, r, g):
    """White where x + y >= 47 (48 x 48): every pixel on x + y = 47 has a left and a top edge (a
    '/' staircase). Away from its ends (more than 16 steps: the diagonal searches stop at 15 with
    the end not found, so no crossing edges) neither end tells how the edge goes on, and the area
    is the mean over the two 45-degree lines through the staircase's outer corners (the step
    pixel lies below it: r = 0; the pixel above is cut in half: g = 1/2) and through its inner
    corners (r = 1/2, g = 0): r = g = 1/4 exactly.
    The reference's texture counts points of a closed 30 x 30 lattice strictly below each line:
    the outer line misses only the step pixel's top-left corner (899 of 900 below) and halves the
    pixel above (435 below, the 30 on the diagonal count as above); the inner line halves the step
    pixel (435) and misses the pixel above (0). r = ((1 - 899/900) + (1 - 435/900)) / 2 = 0.25889,
    g = (435/900 + 0) / 2 = 0.24167; as bytes floor(255 r) = 66, floor(255 g) = 61."""
    n = 48
    yy, xx = np.mgrid[0:n, 0:n]
    img = grey((xx + yy >= n - 1).astype(F))
    out, t = smaa(img, blend_space=blend_space, area=area)
    xs = np.arange(17, 31)
    ys = n - 1 - xs
    assert t["diagonal"][ys, xs].all()
    np.testing.assert_allclose(t["weight_r"][ys, xs], r, atol=1e-7)
    np.testing.assert_allclose(t["weight_g"][ys, xs], g, atol=1e-7)
    assert not t["weight_b"].any()          # diagonals skip the vertical processing
    enc = srgb_encode if blend_space == "linear" else (lambda v: v)
    # the white step pixel takes r of the black one above; the black one g of the white below
    np.testing.assert_allclose(out[ys, xs], np.broadcast_to(enc(1 - r), (len(xs), 3)), atol=2e-6)
    np.testing.assert_allclose(out[ys - 1, xs], np.broadcast_to(enc(g), (len(xs), 3)), atol=2e-6)
    # away from the staircase nothing changes
    far = np.abs(xx + yy - (n - 1)) > 1
    assert np.array_equal(out[far], img[far])


def test_staircase_between_two_flats_gets_the_bent_diagonal_area():
    """A 45-degree run between two horizontal flats: the boundary row is 14 for x <= 10, 24 - x for
    10 <= x <= 19 and 5 for x >= 19 (white below). The diagonal run is x = 10..19 (n = 10; x = 10
    is the bottom end, a pixel with a top edge only, which the search includes). At both ends the
    boundary continues horizontally (crossing code 2 at both ends: a flatter edge), so the line
    runs from the run's first outer corner to the inner corner after its last step: in the '/'
    frame (y up, step pixels [1 + k, 2 + k] x [k, 1 + k]) from (1, 1) to (n + 1, n) = (11, 10),
    y = 1 + 0.9 (x - 1). Pixel x = 12 is step dl = 2 (dr = 7): the square [3, 4] x [2, 3], where
    the line rises from 2.8 to 3.7:
      above the line in the pixel: the triangle left of x = 3 + 0.2 / 0.9: 0.2^2 / 1.8 = 1/45  (r)
      below the line in the pixel above, [3, 4]^2: the triangle right of that x: 0.7^2 / 1.8  (g)
    Pixel x = 15 (dl = 5, dr = 4): the square [6, 7] x [5, 6], the line from 5.5 to 6.4:
      r = 0.5^2 / 1.8 = 0.13888..., g = 0.4^2 / 1.8 = 0.08888..."""
    img = boundary_image(24, 32, lambda x: 24 - min(max(x, 10), 19))
    out, t = smaa(img, blend_space="display", area="exact")
    assert t["diagonal"][24 - np.arange(10, 20), np.arange(10, 20)].all()
    assert t["weight_r"][12, 12] == pytest.approx(0.2 ** 2 / 1.8, abs=1e-6)
    assert t["weight_g"][12, 12] == pytest.approx(0.7 ** 2 / 1.8, abs=1e-6)
    assert t["weight_r"][9, 15] == pytest.approx(0.5 ** 2 / 1.8, abs=1e-6)
    assert t["weight_g"][9, 15] == pytest.approx(0.4 ** 2 / 1.8, abs=1e-6)
    assert out[12, 12, 0] == pytest.approx(1 - 0.2 ** 2 / 1.8, abs=1e-6)
    assert out[11, 12, 0] == pytest.approx(0.7 ** 2 / 1.8, abs=1e-6)
    # the same run with diagonal detection off is handled as short orthogonal segments instead
    _, t0 = smaa(img, blend_space="display", max_search_steps_diag=0, area="exact")
    assert not t0["diagonal"].any() and t0["weight_r"][12, 12] != t["weight_r"][12, 12]
    # mirrored left-right it is a '\' run (the second diagonal search, on top and right edges):
    # the same weights at the mirrored pixels
    xs = np.arange(10, 20)
    _, tm = smaa(img[:, ::-1].copy(), blend_space="display", area="exact")
    assert tm["diagonal"][24 - xs, 31 - xs].all()
    for k in ("weight_r", "weight_g"):
        np.testing.assert_array_equal(tm[k][24 - xs, 31 - xs], t[k][24 - xs, xs])


def test_staircase_between_two_verticals_gets_the_steeper_diagonal_area():
    """The previous image transposed: white iff x >= 24 - clamp(y, 10, 19). Its diagonal run is
    (24 - y, y) for y = 11..19 (n = 9; (14, 10) has a left edge only and ends the run at the top).
    Both ends continue vertically (a steeper edge): the bottom end (5, 19) has its own left edge
    (code 1), the pixel past the top end, (14, 10), has a left edge (code 1), so the line runs from
    the run's first inner corner (1, 0) to the outer corner after its last step, (n + 1, n + 1) =
    (10, 10): y = (10 / 9) (x - 1). Pixel (12, 12) is step dl = 7 (dr = 1): the square
    [8, 9] x [7, 8], where the line rises from 70/9 to 80/9, crossing y = 8 at x = 8.2:
      r = (2/9)^2 / (2 * 10/9) = 1/45,  g = (8/9)^2 / (2 * 10/9) = 32/90."""
    img = boundary_image(24, 32, lambda x: 24 - min(max(x, 10), 19)).transpose(1, 0, 2).copy()
    _, t = smaa(img, blend_space="display", area="exact")
    ys = np.arange(11, 20)
    assert t["diagonal"][ys, 24 - ys].all() and not t["diagonal"][10, 14]
    assert t["weight_r"][12, 12] == pytest.approx(1 / 45, abs=1e-6)
    assert t["weight_g"][12, 12] == pytest.approx(32 / 90, abs=1e-6)


# ------------------------------------------------------------------------------ symmetry
def blocky(seed, h=28, w=32, frame=2, shifts=(-1, 0, 1)):
    """Random 4x4-pixel blocks of 4 grey levels, each row shifted by a random walk of `shifts`
    (stair steps of vertical edges; steps of 1 make 45-degree runs), inside a uniform frame (so no
    edge reaches the image border)."""
    rng = np.random.default_rng(seed)
    base = rng.choice(np.array([0.0, 0.3, 0.65, 1.0], F), size=(h // 4 + 2, w // 4 + 3))
    img = np.kron(base, np.ones((4, 4), F))
    shift = np.cumsum(rng.choice(np.array(shifts), size=h))
    out = np.stack([np.roll(img[y], shift[y])[:w] for y in range(h)])
    out[:frame], out[-frame:], out[:, :frame], out[:, -frame:] = 0.5, 0.5, 0.5, 0.5
    return grey(out)


@pytest.mark.parametrize("seed", [3, 4])
def test_transposed_image_gives_transposed_weights_and_output(seed):
    """Edge search, areas, corners and blending are written once in (along, across) coordinates:
    the transposed image gives exactly the transposed weights (r <-> b, g <-> a). Outputs agree
    except where the blending pass breaks a tie max(horizontal) == max(vertical) (always
    vertical, as in the reference). Diagonal runs are only searched from top edges and blend
    vertically (as in the reference), so they are not transpose-symmetric: checked with diagonal
    detection off on an image with 45-degree runs (row shifts of 1) and, with the default
    settings, on one without (row shifts of 2)."""
    for params, shifts in ((dict(max_search_steps_diag=0), (-1, 0, 1)), (dict(), (-2, 0, 2))):
        img = blocky(seed, shifts=shifts)
        imgT = img.transpose(1, 0, 2).copy()
        out, t = smaa(img, **params)
        outT, tT = smaa(imgT, **params)
        assert not t["diagonal"].any() and not tT["diagonal"].any()
        for a, b in (("weight_r", "weight_b"), ("weight_g", "weight_a"), ("edge_left", "edge_top")):
            assert np.array_equal(t[a], tT[b].T) and np.array_equal(t[b], tT[a].T)
        ax = np.pad(t["weight_a"][:, 1:], ((0, 0), (0, 1)))   # right neighbour's a
        ay = np.pad(t["weight_g"][1:, :], ((0, 1), (0, 0)))   # bottom neighbour's g
        mh, mv = np.maximum(ax, t["weight_b"]), np.maximum(ay, t["weight_r"])
        tie = (mh == mv) & (mh > 0)
        same = ~tie
        assert same.mean() > 0.9 and (t["weight_r"] > 0).sum() > 20
        np.testing.assert_array_equal(out[same], outT.transpose(1, 0, 2)[same])


# ------------------------------------------------------------------------------ scalar oracle
def area_numeric(dl, dr, h_start, h_end, samples=4000):
    """Orthogonal area by midpoint integration of the revectorised line over [dl, dl + 1]:
    (mean of max(-h, 0), mean of max(h, 0)); a U (both heights of one sign) has each half's
    area A smoothed to lerp(sqrt(2 A) / 2, A, min(d / 32, 1))."""
    d = dl + dr + 1
    m = d / 2
    t = dl + (np.arange(samples) + 0.5) / samples
    h = np.where(t <= m, h_start * (m - t) / m, h_end * (t - m) / m)
    k = min(d / 32, 1.0)
    out = [0.0, 0.0]
    for half in (t <= m, t > m):
        for i, part in enumerate((np.maximum(-h, 0), np.maximum(h, 0))):
            a = part[half].sum() / samples
            if h_start * h_end > 0:
                a = np.sqrt(2 * a) / 2 + (a - np.sqrt(2 * a) / 2) * k
            out[i] += a
    return out[0], out[1]


def pattern_heights(c1, c2):
    """Heights at the two ends from the crossing codes (1: above, +1/2; 3: below, -1/2; 0: none);
    an end with crossing edges on both sides (4) takes the opposite of a single bend at the other
    end (a Z) and stays flat otherwise."""
    bend = {0: 0.0, 1: 0.5, 3: -0.5}
    h1, h2 = bend.get(c1), bend.get(c2)
    if h1 is None:
        h1 = -h2 if h2 is not None else 0.0
    if h2 is None:
        h2 = -bend[c1] if c1 in bend else 0.0
    return h1, h2


def oracle_ortho_weights(el, et, steps=32, rounding=25.0):
    """Blending weights of the orthogonal patterns, walking the edges pixel by pixel (no pseudo
    gather, no search table): from each pixel with a top edge walk left / right while the next
    pixel has a top edge and no crossing (left) edge separates them; the crossing edges at the
    ends give the heights (code = above + 3 * below, `pattern_heights`), areas by numerical
    integration, then corner rounding. Left edges: the same on the transposed edge maps."""
    def one_dir(cont, cross):       # cont: edges along rows (top), cross: left edges
        h, w = cont.shape
        rr, gg = np.zeros((h, w)), np.zeros((h, w))
        at = lambda a, x, y: a[min(max(y, 0), h - 1), min(max(x, 0), w - 1)]  # noqa: E731
        for y in range(h):
            for x in range(w):
                if not cont[y, x]:
                    continue
                xl = x
                while xl - 1 >= 0 and cont[y, xl - 1] and not (cross[y, xl] or at(cross, xl, y - 1)):
                    xl -= 1
                xr = x
                while (xr + 1 < w and cont[y, xr + 1]
                       and not (cross[y, xr + 1] or at(cross, xr + 1, y - 1))):
                    xr += 1
                dl, dr = x - xl, xr - x
                assert dl <= 2 * steps - 1 and dr <= 2 * steps   # within the search range
                c1 = at(cross, xl, y - 1) + 3 * at(cross, xl, y)
                c2 = at(cross, xr + 1, y - 1) + 3 * at(cross, xr + 1, y)
                r, g = area_numeric(dl, dr, *pattern_heights(c1, c2))
                near_l, near_r = float(dl <= dr), float(dr <= dl)
                k = (1 - rounding / 100) / (near_l + near_r)
                fr = 1 - k * near_l * at(cross, xl, y + 1) - k * near_r * at(cross, xr + 1, y + 1)
                fg = 1 - k * near_l * at(cross, xl, y - 2) - k * near_r * at(cross, xr + 1, y - 2)
                rr[y, x], gg[y, x] = r * min(max(fr, 0), 1), g * min(max(fg, 0), 1)
        return rr, gg

    r, g = one_dir(et, el)
    bT, aT = one_dir(el.T.copy(), et.T.copy())
    return r, g, bT.T, aT.T


@pytest.mark.parametrize("seed", [5, 6, 7])
def test_orthogonal_weights_match_a_pixel_walking_oracle(seed):
    img = blocky(seed, h=24, w=28)
    _, t = smaa(img, max_search_steps_diag=0, area="exact")
    el, et = t["edge_left"].astype(bool), t["edge_top"].astype(bool)
    assert el.sum() > 20 and et.sum() > 20
    r, g, b, a = oracle_ortho_weights(el, et)
    for name, ref in (("weight_r", r), ("weight_g", g), ("weight_b", b), ("weight_a", a)):
        np.testing.assert_allclose(t[name], ref, atol=2e-6, err_msg=name)
    assert (r > 0).sum() > 10 and (b > 0).sum() > 10


# ------------------------------------------------------------------------------ blending pass
def numpy_neighbourhood_blend(rgb, R, G, B, A, linear, eps=1e-5):
    """SMAANeighborhoodBlendingPS in NumPy (float64), clamp-to-edge bilinear fetches."""
    h, w = R.shape
    src = srgb_decode(rgb) if linear else rgb.astype(np.float64)

    def bil(px, py):
        # positions are float32 texture coordinates, as in the shader (their rounding matters:
        # with sRGB encoding after the mix it is amplified up to ~7x near black)
        px, py = px.astype(F), py.astype(F)
        u, v = np.clip(px - F(0.5), -1, w), np.clip(py - F(0.5), -1, h)
        x0, y0 = np.floor(u).astype(int), np.floor(v).astype(int)
        tx, ty = (u - x0)[..., None], (v - y0)[..., None]
        X0, X1 = np.clip(x0, 0, w - 1), np.clip(x0 + 1, 0, w - 1)
        Y0, Y1 = np.clip(y0, 0, h - 1), np.clip(y0 + 1, 0, h - 1)
        top = src[Y0, X0] * (1 - tx) + src[Y0, X1] * tx
        bot = src[Y1, X0] * (1 - tx) + src[Y1, X1] * tx
        return top * (1 - ty) + bot * ty

    ax = np.pad(A[:, 1:], ((0, 0), (0, 1)), mode="edge")   # clamp-to-edge: the last column
    ay = np.pad(G[1:, :], ((0, 1), (0, 0)), mode="edge")   # reads its own a, the bottom row its g
    az, aw = B, R
    horiz = np.maximum(ax, az) > np.maximum(ay, aw)
    w1, w2 = np.where(horiz, ax, ay), np.where(horiz, az, aw)
    s = np.where(w1 + w2 > 0, w1 + w2, 1)
    yy, xx = (np.mgrid[0:h, 0:w] + 0.5).astype(F)
    c1 = bil(xx + np.where(horiz, ax, F(0)), yy + np.where(horiz, F(0), ay))
    c2 = bil(xx - np.where(horiz, az, F(0)), yy - np.where(horiz, F(0), aw))
    mixed = (w1 / s)[..., None] * c1 + (w2 / s)[..., None] * c2
    if linear:
        mixed = srgb_encode(np.clip(mixed, 0, 1))
    out = np.clip(mixed, 0, 1)
    keep = (ax + ay + az + aw) < eps
    return np.where(keep[..., None], rgb, out)


@pytest.mark.parametrize("blend_space", ["display", "linear"])
def test_neighbourhood_blending_matches_numpy_on_random_weights(blend_space):
    rng = np.random.default_rng(11)
    h, w = 13, 17
    rgb = rng.random((h, w, 3)).astype(F)
    weights = [(rng.random((h, w)) * 0.6 * (rng.random((h, w)) < 0.5)).astype(F) for _ in range(4)]
    weights[0][2, 3] = weights[2][2, 3] = 0.3            # an exact tie: goes vertical
    grid = K.Grid(w, h)
    out = neighbourhood_blend(grid, dr.unravel(mi.Color3f, mi.Float(rgb.reshape(-1))),
                              tuple(mi.Float(a.reshape(-1)) for a in weights),
                              SMAAParams(blend_space=blend_space))
    out = np.asarray(dr.ravel(out), F).reshape(h, w, 3)
    ref = numpy_neighbourhood_blend(rgb, *weights, linear=blend_space == "linear")
    np.testing.assert_allclose(out, ref, atol=1e-6, rtol=0)
    keep = np.all(out == rgb, axis=-1)
    assert 0 < keep.sum() < h * w                         # some pixels blended, some kept exactly

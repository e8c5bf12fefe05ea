"""The baseline TAA's extension switches (taa_impl/baseline.py): Dr.Jit against the NumPy oracle with each
switch on, and a hand-computed case for each."""
from __future__ import annotations

import numpy as np
import pytest

import backend  # noqa: F401  (before anything touches drjit)
from backend import dr, mi

import taa_impl
from taa_impl import kernels as K
from tests.oracle_taa import OracleTAA
from tests.test_taa import random_frames, still_frame

F = np.float32


def ravel(x, n_channels=3):
    return np.asarray(dr.ravel(x) if n_channels > 1 else x, np.float64).reshape(-1, n_channels)


# ----------------------------------------------------------------------------- oracle agreement
SWITCHES = [
    ("taa_baseline", {"box": "ycocg"}),
    ("taa_baseline", {"variance_clip_gamma": 1.0}),
    ("taa_baseline", {"variance_clip_gamma": 1.25, "variance_intersect": True}),
    ("taa_baseline", {"box": "ycocg", "variance_clip_gamma": 0.75, "variance_intersect": True}),
    ("taa_baseline", {"history_filter": "catmull_rom"}),
    ("taa_baseline", {"history_filter": "catmull_rom_5"}),
    ("taa_baseline", {"tonemap_blend": True}),
    ("taa_baseline", {"tonemap_blend": True, "tonemap_luma": (0.25, 0.5, 0.25)}),
    ("taa_baseline", {"reject_depth": 0.02}),
    ("taa_baseline", {"reject_id": True}),
    ("taa_reject", {}),
    ("taa_ycocg_variance", {}),
    ("taa_ycocg_variance", {"feedback": "inside", "sharpen": "normalised"}),
    ("taa_improved", {"history_filter": "catmull_rom", "tonemap_blend": True}),
    ("taa_improved", {"reject_depth": 0.02, "reject_id": True, "history_filter": "catmull_rom_5"}),
]


@pytest.mark.parametrize("name,overrides", SWITCHES)
def test_switch_matches_numpy_oracle(name, overrides):
    frames = random_frames(seed=17 + len(overrides), n=6, h=12, w=16)
    tech = taa_impl.make(name, **overrides)
    oracle = OracleTAA(tech.params, improved=name == "taa_improved")
    rejected = 0
    for i, fr in enumerate(frames):
        reset = i == 4
        out = tech.process(fr, jitter=(0.25, -0.125), far=100.0, reset=reset)
        ref = oracle.process(fr, far=100.0, reset=reset)
        np.testing.assert_allclose(out, ref, rtol=1e-5, atol=1e-5, err_msg=f"frame {i}")
        np.testing.assert_allclose(tech.history, oracle.history, rtol=1e-5, atol=1e-5)
        if oracle.rejected is not None:
            got = tech.debug_terms()["history_rejected"]
            np.testing.assert_array_equal(got, oracle.rejected.astype(F))
            rejected += int(oracle.rejected.sum())
    if tech.params.rejects:
        assert 0 < rejected < 5 * 12 * 16  # the test was exercised both ways


def test_switches_default_off_and_validated():
    p = taa_impl.make("taa_baseline").params
    assert (p.box, p.variance_clip_gamma, p.variance_intersect, p.history_filter, p.tonemap_blend,
            p.reject_depth, p.reject_id) == ("minmax", None, False, "bilinear", False, None, False)
    assert taa_impl.make("taa_baseline").needs == {"color", "depth", "motion"}
    assert taa_impl.make("taa_baseline", reject_depth=0.1).needs == {"color", "depth", "motion", "prev_depth"}
    assert taa_impl.make("taa_baseline", reject_id=True).needs == {"color", "depth", "motion", "object_id"}
    for bad in ({"box": "hsv"}, {"variance_clip_gamma": -1.0}, {"variance_clip_gamma": float("nan")},
                {"history_filter": "lanczos"}, {"reject_depth": -0.1}, {"tonemap_luma": (1, 2)}):
        with pytest.raises(ValueError):
            taa_impl.make("taa_baseline", **bad)
    # the box switches are the baseline's; the improved TAA builds its own box
    for bad in ({"box": "ycocg"}, {"variance_clip_gamma": 1.0}):
        with pytest.raises(ValueError):
            taa_impl.make("taa_improved", **bad)


@pytest.mark.parametrize("name", ["taa_ycocg", "taa_variance", "taa_catmull_rom", "taa_tonemap_blend",
                                  "taa_reject", "taa_ycocg_variance"])
@pytest.mark.parametrize("sharpen", ["xu", "none"])
def test_constant_image_stays_exactly_constant(name, sharpen):
    # every switch keeps a constant image bit-exact whatever the motion, depths and IDs (the
    # Catmull-Rom taps and the Karis weight are written so; YCoCg needs the dyadic values below)
    rng = np.random.default_rng(8)
    h, w = 10, 12
    c = np.empty((h, w, 3), F)
    c[:] = (0.25, 1.5, 0.125)     # dyadic: the YCoCg round trip of these values is exact
    t = taa_impl.make(name, sharpen=sharpen)
    for i in range(8):
        fr = still_frame(c, depth=rng.uniform(1, 90, (h, w)), ids=rng.integers(0, 4, (h, w)))
        fr["motion"] = rng.normal(0, 3, (h, w, 2)).astype(F)
        out = t.process(fr, jitter=(0, 0), far=100.0)
        assert np.array_equal(out, c), f"frame {i}"


# --------------------------------------------------------------------------------- YCoCg
def test_ycocg_by_hand_and_round_trip():
    rgb = mi.Color3f(mi.Float([1, 1, 0, 0, 0.5]), mi.Float([1, 0, 1, 0, 0.25]), mi.Float([1, 0, 0, 1, 0.75]))
    y = ravel(K.rgb_to_ycocg(rgb))
    np.testing.assert_array_equal(y, [[1, 0, 0], [0.25, 0.5, -0.25], [0.5, 0, 0.5], [0.25, -0.5, -0.25],
                                      [0.4375, -0.125, -0.1875]])
    # dyadic values: exact round trip
    rng = np.random.default_rng(0)
    vals = (rng.integers(0, 4096, (200, 3)) / 1024.0).astype(F)
    c = dr.unravel(mi.Color3f, mi.Float(vals.reshape(-1)))
    back = ravel(K.ycocg_to_rgb(K.rgb_to_ycocg(c)))
    np.testing.assert_array_equal(back, vals)
    # arbitrary floats: within a few ulp
    vals = rng.uniform(0, 100, (200, 3)).astype(F)
    c = dr.unravel(mi.Color3f, mi.Float(vals.reshape(-1)))
    back = ravel(K.ycocg_to_rgb(K.rgb_to_ycocg(c)))
    np.testing.assert_allclose(back, vals, rtol=0, atol=4 * 100 * 2.0 ** -24 * 4)


def test_ycocg_clip_differs_from_rgb_clip():
    # history magenta against a box of greys: the RGB box and the YCoCg box clip to different points
    box_lo, box_hi = mi.Color3f(0.4, 0.4, 0.4), mi.Color3f(0.6, 0.6, 0.6)
    hist = mi.Color3f(1.0, 0.0, 1.0)
    rgb = ravel(K.clip_toward_centre(hist, box_lo, box_hi, 1e-8))
    yc = ravel(K.ycocg_to_rgb(K.clip_toward_centre(K.rgb_to_ycocg(hist), K.rgb_to_ycocg(box_lo),
                                                    K.rgb_to_ycocg(box_hi), 1e-8)))
    # RGB: v = (0.5, -0.5, 0.5), e = 0.1 -> m = 5 -> p + v/5 = (0.6, 0.4, 0.6)
    np.testing.assert_allclose(rgb, [[0.6, 0.4, 0.6]], atol=1e-6)
    # YCoCg: grey box is Y in [0.4, 0.6], Co = Cg = 0 (+eps); magenta is (0.5, 0, -0.5): m = 0.5/1e-8
    # -> pulled onto the grey axis at Y = 0.5 (within 1e-7)
    np.testing.assert_allclose(yc, [[0.5, 0.5, 0.5]], atol=1e-6)


# ------------------------------------------------------------------------------ variance box
def test_variance_box_by_hand():
    img = np.zeros((3, 3), F)
    img[1, 1] = 9.0
    grid = K.Grid(3, 3)
    lo, hi, mu = K.variance_box(grid, mi.Float(img.reshape(-1)), 1.0)
    # centre: values eight 0 and one 9: mu = 1, sigma^2 = (8 * 1 + 64) / 9 = 8
    assert np.asarray(mu)[4] == pytest.approx(1.0, abs=1e-6)
    assert np.asarray(lo)[4] == pytest.approx(1 - np.sqrt(8), rel=1e-6)   # below the min (0)
    assert np.asarray(hi)[4] == pytest.approx(1 + np.sqrt(8), rel=1e-6)
    lo2, hi2, _ = K.variance_box(grid, mi.Float(img.reshape(-1)), 0.5)
    assert np.asarray(hi2)[4] == pytest.approx(1 + 0.5 * np.sqrt(8), rel=1e-6)


def test_variance_box_of_constant_neighbourhood_has_zero_size():
    h, w = 6, 7
    grid = K.Grid(w, h)
    for value in (0.1234567, 3.3333333, 1e4, 0.0):
        c = mi.Color3f(value, 2 * value, value / 3)
        lo, hi, mu = K.variance_box(grid, dr.zeros(mi.Color3f, grid.n) + c, 1.0)
        lo, hi, mu = ravel(lo), ravel(hi), ravel(mu)
        assert np.all(np.isfinite(lo)) and np.array_equal(lo, hi) and np.array_equal(lo, mu)
        np.testing.assert_array_equal(mu, np.broadcast_to(ravel(c)[0], mu.shape))
    # through the TAA: a history far off a constant frame is clipped onto the point, no NaN
    t = taa_impl.make("taa_variance", sharpen="none")
    t.process(still_frame(np.full((h, w, 3), 0.2, F)), jitter=(0, 0), far=100.0)
    for value in (0.7, 1e4, 0.0):
        out = t.process(still_frame(np.full((h, w, 3), value, F)), jitter=(0, 0), far=100.0)
        assert np.all(np.isfinite(out))
        np.testing.assert_allclose(out, value, atol=1e-7 + 1e-7 * value)


def test_variance_intersection_stays_inside_minmax_box():
    # a lone bright pixel: the variance box reaches below 0; the intersection does not
    c = np.zeros((5, 5, 3), F)
    c[2, 2] = 9.0
    for intersect, expect_lo in ((False, 1 - np.sqrt(8)), (True, 0.0)):
        t = taa_impl.make("taa_variance", variance_intersect=intersect)
        t.process(still_frame(c), jitter=(0, 0), far=100.0)
        lo = t.debug_terms()["box_min"][2, 2]
        np.testing.assert_allclose(lo, expect_lo, rtol=1e-6, atol=1e-7)


# ------------------------------------------------------------------------------ Catmull-Rom
@pytest.mark.parametrize("five_tap", [False, True])
def test_catmull_rom_reproduces_a_linear_ramp(five_tap):
    w, h = 12, 10
    grid = K.Grid(w, h)
    ramp = 0.5 + 0.25 * mi.Float(grid.x) - 0.125 * mi.Float(grid.y)
    ys, xs = np.indices((h, w))
    offsets = [(0.3, 0.0), (-0.75, 0.0), (0.5, 1.0)] if five_tap else \
        [(0.3, 0.7), (-0.25, 0.5), (1.6, -0.4), (0.5, 0.0)]
    for vx, vy in offsets:
        px = mi.Float(grid.x) + 0.5 - vx
        py = mi.Float(grid.y) + 0.5 - vy
        got = np.asarray(K.catmull_rom(grid, ramp, px, py, five_tap=five_tap)).reshape(h, w)
        want = 0.5 + 0.25 * (xs - vx) - 0.125 * (ys - vy)
        inner = (slice(3, h - 3), slice(3, w - 3))          # the 4x4 footprint inside the image
        np.testing.assert_allclose(got[inner], want[inner], atol=2e-6)


def test_catmull_rom_weights_and_overshoot():
    t = mi.Float([0.0, 0.25, 0.5, 0.999])
    ws = np.array([np.asarray(x) for x in K.catmull_rom_weights(t)])
    np.testing.assert_allclose(ws.sum(axis=0), 1.0, atol=1e-7)
    np.testing.assert_array_equal(ws[:, 0], [0, 1, 0, 0])                   # integer: the texel
    np.testing.assert_allclose(ws[:, 2], [-0.0625, 0.5625, 0.5625, -0.0625])  # half way
    # a step 0 | 1 sampled a quarter pixel past the step overshoots: negative lobe
    grid = K.Grid(8, 1)
    step = mi.Float([0, 0, 0, 0, 1, 1, 1, 1])
    v = np.asarray(K.catmull_rom(grid, step, mi.Float(grid.x) + 0.75, dr.zeros(mi.Float, 8) + 0.5))
    assert v[2] < 0 and v[4] > 1


def test_catmull_rom_negative_lobe_is_clipped_by_the_box():
    # history: a hard step; the camera moves by half a pixel: Catmull-Rom overshoots below 0 and
    # above 1; the box of the current frame (0 and 1 only) clips it, so the history stays in [0, 1]
    h, w = 6, 12
    c = np.zeros((h, w, 3), F)
    c[:, 6:] = 1.0
    t = taa_impl.make("taa_catmull_rom", sharpen="none")
    t.process(still_frame(c), jitter=(0, 0), far=100.0)
    fr = still_frame(c)
    fr["motion"][:] = (0.5, 0.0)
    out = t.process(fr, jitter=(0, 0), far=100.0)
    assert out.min() >= 0.0 and out.max() <= 1.0
    assert t.history.min() >= 0.0 and t.history.max() <= 1.0


def test_catmull_rom_at_integer_motion_equals_bilinear():
    # at whole-pixel motion the weights are (0, 1, 0, 0): the texel itself, as bilinear gives
    frames = random_frames(seed=21, n=4, h=10, w=12)
    for fr in frames:
        fr["motion"] = np.round(fr["motion"]).astype(F)
    t1, t2 = taa_impl.make("taa_baseline"), taa_impl.make("taa_catmull_rom")
    for fr in frames:
        assert np.array_equal(t1.process(fr, jitter=(0, 0), far=100.0),
                              t2.process(fr, jitter=(0, 0), far=100.0))
    assert not np.array_equal(t1.history, frames[-1]["color"])   # the history was used


# ----------------------------------------------------------------------- Karis tone-map blend
def test_karis_weight_by_hand():
    # c = 0 (w_c = 1), h = (3, 3, 3) (luma 3, w_h = 1/4), k = 0.9:
    # T-space: T(c) = 0, T(h) = 0.75, mix = 0.675, back: 0.675 / (1 - 0.675) = 2.0769... = 3 k'
    # k' = 0.9 / 4 / (0.1 + 0.225) = 0.6923...
    k = K.karis_blend_weight(mi.Color3f(0.0), mi.Color3f(3.0), mi.Float(0.9), K.REC709)
    assert np.asarray(k)[0] == pytest.approx(0.225 / 0.325, rel=1e-6)
    assert 3 * np.asarray(k)[0] == pytest.approx(0.675 / 0.325, rel=1e-6)
    # equal lumas: the weight is k itself
    k = K.karis_blend_weight(mi.Color3f(0.5, 0.1, 0.2), mi.Color3f(0.5, 0.1, 0.2), mi.Float(0.93), K.REC709)
    assert np.asarray(k)[0] == pytest.approx(0.93, rel=1e-6)


def test_karis_weight_equals_tonemapped_blend():
    rng = np.random.default_rng(2)
    c = rng.uniform(0, 20, (500, 3)).astype(F)
    h = rng.uniform(0, 20, (500, 3)).astype(F)
    k = rng.uniform(0.8, 1.0, 500).astype(F)
    kk = np.asarray(K.karis_blend_weight(dr.unravel(mi.Color3f, mi.Float(c.reshape(-1))),
                                         dr.unravel(mi.Color3f, mi.Float(h.reshape(-1))),
                                         mi.Float(k), K.REC709), np.float64)
    got = c + kk[:, None] * (h - c)
    lum = lambda x: (x.astype(np.float64) @ np.array(K.REC709))[:, None]  # noqa: E731
    tc, th = c / (1 + lum(c)), h / (1 + lum(h))
    tm = tc + k[:, None] * (th - tc)
    want = tm / (1 - lum(tm))
    np.testing.assert_allclose(got, want, rtol=2e-6, atol=20 * 2e-7)  # float32 weights, values <= 20
    # and T^-1(T(x)) = x
    np.testing.assert_allclose(tc / (1 - lum(tc)), c, rtol=1e-12)


def test_tonemap_blend_damps_a_firefly():
    # history 1 everywhere; one frame has a 1000x firefly at one pixel whose box lets it through
    # (its neighbours' box spans it). Linear blending keeps (1 - k) * 1000 of it; Karis's weighting
    # keeps far less.
    h, w = 5, 5
    base = np.ones((h, w, 3), F)
    fire = base.copy()
    fire[2, 2] = 1000.0
    outs = {}
    for tb in (False, True):
        t = taa_impl.make("taa_baseline", tonemap_blend=tb, sharpen="none")
        t.process(still_frame(base), jitter=(0, 0), far=100.0)
        outs[tb] = t.process(still_frame(fire), jitter=(0, 0), far=100.0)[2, 2, 0]
    # the box at the firefly is (min 1, max (1000 + 1000)/2 = 1000), history 1 is inside: no clip
    # d = 999/1000 -> k = k_min + (k_max - k_min) (1 - 0.999)^2
    p = taa_impl.make("taa_baseline").params
    k = p.k_min + (p.k_max - p.k_min) * (1 - 999 / 1000) ** 2
    assert outs[False] == pytest.approx(1000 + k * (1 - 1000), rel=1e-5)
    wc, wh = 1 / 1001, 1 / 2
    kk = k * wh / ((1 - k) * wc + k * wh)
    assert outs[True] == pytest.approx(1000 + kk * (1 - 1000), rel=1e-5)
    assert outs[True] < outs[False] / 50


# ------------------------------------------------------------------------------- rejection
def _moving_block(depth_bg=50.0, depth_fg=5.0, same_depth=False):
    """Frame 0: an object (id 2) over columns 2..5; frame 1: it moved 3 px right (cols 5..8).
    Noisy background (id 1), redrawn every frame, so its box is not a point and a kept history
    differs from the current colour."""
    h, w = 6, 14
    rng = np.random.default_rng(5)
    frames = []
    for x0, mv in ((2, 0.0), (5, 3.0)):
        c = rng.uniform(0.2, 0.4, (h, w, 3)).astype(F)      # new noise each frame, like jitter
        depth = np.full((h, w), depth_bg, F)
        ids = np.ones((h, w), np.int32)
        motion = np.zeros((h, w, 2), F)
        c[:, x0:x0 + 4] = (5.0, 0.0, 0.0)
        depth[:, x0:x0 + 4] = depth_bg if same_depth else depth_fg
        ids[:, x0:x0 + 4] = 2
        motion[:, x0:x0 + 4] = (mv, 0.0)
        frames.append(dict(color=c, depth=depth, prev_depth=depth.copy(), object_id=ids, motion=motion))
    return frames


@pytest.mark.parametrize("switch", [{"reject_depth": 0.05}, {"reject_id": True}])
def test_rejection_on_a_disocclusion(switch):
    same_depth = "reject_id" in switch          # the ID test must work without any depth change
    f0, f1 = _moving_block(same_depth=same_depth)
    t = taa_impl.make("taa_baseline", sharpen="none", **switch)
    t.process(f0, jitter=(0, 0), far=100.0)
    out = t.process(f1, jitter=(0, 0), far=100.0)
    rej = t.debug_terms()["history_rejected"]
    # columns 2 and 3 were covered by the object and are background now, at least 2 px from the
    # object (so their velocity is the background's, 0): rejected -> exactly the current colour
    assert np.all(rej[:, 2:4] == 1)
    np.testing.assert_array_equal(out[:, 2:4], f1["color"][:, 2:4])
    # background that stayed background, and the object that moved with its motion: kept
    assert np.all(rej[:, 10:] == 0) and np.all(rej[:, 6:9] == 0)
    assert not np.array_equal(out[:, 11:], f1["color"][:, 11:])
    # without rejection the same pixels keep a (clipped) history: not the current colour
    t0 = taa_impl.make("taa_baseline", sharpen="none")
    t0.process(f0, jitter=(0, 0), far=100.0)
    plain = t0.process(f1, jitter=(0, 0), far=100.0)
    assert not np.array_equal(plain[:, 2:4], f1["color"][:, 2:4])


def test_depth_rejection_threshold_is_relative():
    f0, f1 = _moving_block()
    # the moved object says it was at depth 5.0 last frame (its prev_depth); the stored depth buffer
    # at its previous position shows 5.2: a relative difference of 4%
    f0 = {k: v.copy() for k, v in f0.items()}
    f0["depth"][f0["object_id"] == 2] = 5.2
    for thr, expect in ((0.05, 0), (0.03, 1)):
        t = taa_impl.make("taa_baseline", reject_depth=thr)
        t.process(f0, jitter=(0, 0), far=100.0)
        t.process(f1, jitter=(0, 0), far=100.0)
        assert np.all(t.debug_terms()["history_rejected"][:, 6:9] == expect)


# ------------------------------------------------------------------------------- presets
def test_presets():
    t = taa_impl.make("taa_ycocg_variance")
    assert t.name == "taa_ycocg_variance" and isinstance(t, taa_impl.BaselineTAA)
    p = t.params
    assert (p.box, p.variance_clip_gamma, p.history_filter, p.tonemap_blend) == ("ycocg", 1.0, "catmull_rom", True)
    assert t.sampling == "sequence" and t.output_space == "linear"
    t2 = taa_impl.make("taa_ycocg_variance", variance_clip_gamma=1.5, feedback="inside")
    assert (t2.params.variance_clip_gamma, t2.params.k_min, t2.params.box) == (1.5, 0.88, "ycocg")
    t3 = taa_impl.make("taa_reject", params=taa_impl.TAAParams())
    assert t3.params == taa_impl.TAAParams() and t3.needs == {"color", "depth", "motion"}
    r = taa_impl.make("taa_reject")
    assert (r.params.reject_depth, r.params.reject_id) == (0.05, True)
    assert r.needs == {"color", "depth", "motion", "prev_depth", "object_id"}
    assert hash(r.params) == hash(taa_impl.make("taa_reject").params)

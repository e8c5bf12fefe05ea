"""Tests of taa_impl: Dr.Jit TAAs against the NumPy oracle, and hand-computed cases."""
from __future__ import annotations

import numpy as np
import pytest

import backend  # noqa: F401  (before anything touches drjit)
from backend import dr, mi

import taa_impl
from taa_impl import kernels as K
from taa_impl.base import sharpen_weight
from tests.oracle_taa import OracleTAA

F = np.float32
NAMES = ["taa_baseline", "taa_improved"]


# --------------------------------------------------------------------------------------- helpers
def random_frames(seed, n, h=16, w=24, far=100.0):
    """Random but structured buffers: a smooth background plane (depth gate closed) and rectangles
    of other models, noisy colours, fractional motion, a few off-screen velocities."""
    rng = np.random.default_rng(seed)
    frames = []
    for _ in range(n):
        ys, xs = np.indices((h, w))
        depth = (60 + 0.002 * xs + 0.001 * ys).astype(F)          # nearly flat: gated
        ids = np.zeros((h, w), np.int32)
        for oid in (1, 2, 3):
            x0, y0 = rng.integers(0, w - 4), rng.integers(0, h - 4)
            ww, hh = rng.integers(3, 9), rng.integers(3, 7)
            ids[y0:y0 + hh, x0:x0 + ww] = oid
            depth[y0:y0 + hh, x0:x0 + ww] = rng.uniform(5, 50) + rng.uniform(0, 3, (h, w))[y0:y0 + hh, x0:x0 + ww]
        motion = rng.normal(0, 1.5, (h, w, 2)).astype(F)
        motion[rng.random((h, w)) < 0.05] = (3 * w, -2 * h)          # off-screen
        frames.append(dict(
            color=rng.uniform(0, 1.5, (h, w, 3)).astype(F),
            albedo=rng.uniform(0, 1, (h, w, 3)).astype(F),
            depth=depth,
            prev_depth=(depth + rng.normal(0, 0.5, (h, w))).astype(F),
            object_id=ids,
            motion=motion,
        ))
    return frames


def still_frame(color, depth=10.0, ids=None, albedo=None):
    h, w = color.shape[:2]
    d = np.full((h, w), depth, F) if np.isscalar(depth) else np.asarray(depth, F)
    return dict(color=np.asarray(color, F),
                albedo=np.ones((h, w, 3), F) * 0.5 if albedo is None else np.asarray(albedo, F),
                depth=d, prev_depth=d.copy(),
                object_id=np.ones((h, w), np.int32) if ids is None else np.asarray(ids, np.int32),
                motion=np.zeros((h, w, 2), F))


def run(tech, frames, far=100.0, resets=()):
    return [tech.process(fr, jitter=(0.1 * i % 0.5, -0.2), far=far, reset=i in resets)
            for i, fr in enumerate(frames)]


# ------------------------------------------------------------------------------ registry, params
def test_registry_and_params():
    assert set(NAMES) <= set(taa_impl.TECHNIQUES)
    b = taa_impl.make("taa_baseline", feedback="inside")
    assert (b.params.k_min, b.params.k_max) == (0.88, 0.97)
    assert b.needs == {"color", "depth", "motion"}
    i = taa_impl.make("taa_improved")
    assert (i.params.k_min, i.params.k_max, i.params.sharpen) == (0.925, 0.979, "normalised")
    assert i.params.depth_threshold == 0.002
    assert (i.params.sobel_weight_albedo, i.params.sobel_weight_color, i.params.sobel_weight_depth) == (0.3, 0.7, 1.0)
    assert i.needs == {"color", "albedo", "depth", "prev_depth", "object_id", "motion"}
    assert hash(i.params) == hash(taa_impl.make("taa_improved").params)
    assert hash(b.params) != hash(taa_impl.make("taa_baseline").params)
    with pytest.raises(ValueError):
        taa_impl.make("taa_baseline", feedback="inside", k_min=0.5)
    with pytest.raises(ValueError):
        taa_impl.make("taa_baseline", clip_eps=0.0)
    with pytest.raises(KeyError):
        taa_impl.make("nope")
    with pytest.raises(KeyError):
        b.process({"color": np.zeros((4, 4, 3), F)}, jitter=(0, 0), far=1.0)
    for name, w in (("xu", 1.0), ("normalised", 0.25), ("none", 0.0)):
        assert sharpen_weight(name) == w
        assert np.sum(taa_impl.SHARPEN_KERNELS[name]) == pytest.approx(1.0)


# ----------------------------------------------------------------------------- oracle agreement
@pytest.mark.parametrize("name,overrides", [
    ("taa_baseline", {}),
    ("taa_baseline", {"feedback": "inside", "sharpen": "normalised"}),
    ("taa_improved", {}),
    ("taa_improved", {"feedback": "inside", "sharpen": "xu"}),
])
def test_matches_numpy_oracle(name, overrides):
    frames = random_frames(seed=len(name) + len(overrides), n=7)
    tech = taa_impl.make(name, **overrides)
    oracle = OracleTAA(tech.params, improved=name == "taa_improved")
    gated = 0
    for i, fr in enumerate(frames):
        reset = i == 4  # a camera cut in the middle
        out = tech.process(fr, jitter=(0.25, -0.125), far=100.0, reset=reset)
        ref = oracle.process(fr, far=100.0, reset=reset)
        np.testing.assert_allclose(out, ref, rtol=1e-5, atol=1e-5, err_msg=f"frame {i}")
        np.testing.assert_allclose(tech.history, oracle.history, rtol=1e-5, atol=1e-5)
        if name == "taa_improved":
            terms = tech.debug_terms()
            for key, val in oracle.terms.items():
                # depth(T)PV are 2nd/4th powers of a ratio whose denominator (maxDepthDistance)
                # suffers cancellation: a 1-ulp difference in z/far (Dr.Jit divides by a constant
                # via its reciprocal) shows up as ~3e-5 relative there, so 1e-4 for those two
                rtol = 1e-4 if key.startswith("depth") else 1e-5
                np.testing.assert_allclose(terms[key], val, rtol=rtol, atol=1e-5, err_msg=key)
            gated += int(np.sum(terms["maxDepthDistance"] < 0.002))
            a = terms["aliasedValue"]
            assert 0 < np.mean(a) < 1 and np.all((a >= 0) & (a <= 1))
    if name == "taa_improved":
        assert gated > 0  # the depth gate was exercised both ways


# ------------------------------------------------------------------------------- kernel pieces
def test_clip_feedback_bilinear_by_hand():
    box_min, box_max = mi.Color3f(0, 0, 0), mi.Color3f(1, 1, 1)
    out = K.clip_toward_centre(mi.Color3f(2.0, 0.5, 0.5), box_min, box_max, 1e-8)
    np.testing.assert_allclose(np.array(dr.ravel(out)), [1.0, 0.5, 0.5], atol=1e-6)
    inside = K.clip_toward_centre(mi.Color3f(0.9, 0.1, 0.5), box_min, box_max, 1e-8)
    np.testing.assert_array_equal(np.array(dr.ravel(inside)), np.array([0.9, 0.1, 0.5], F))
    # zero-size box, history on and off the point: finite, onto the point within eps
    pt = mi.Color3f(0.3, 0.3, 0.3)
    for h in (mi.Color3f(0.3, 0.3, 0.3), mi.Color3f(1e4, 0.0, 0.3)):
        v = np.array(dr.ravel(K.clip_toward_centre(h, pt, pt, 1e-8)))
        assert np.all(np.isfinite(v)) and np.allclose(v, 0.3, atol=1e-7)
    # d = 0.5/1 -> w = 0.25;  d = 0.05/0.2 (the floor) -> w = 0.5625
    k = K.feedback_weight(mi.Float(1.0, 0.1), mi.Float(0.5, 0.05), 0.925, 0.979, 0.2)
    np.testing.assert_allclose(np.array(k), [0.925 + 0.054 * 0.25, 0.925 + 0.054 * 0.5625], atol=1e-7)
    # bilinear: hist(x, y) = x + 10 y sampled at velocity (0.25, 0.5) is (x - 0.25) + 10 (y - 0.5)
    w, h = 6, 5
    grid = K.Grid(w, h)
    hist = mi.Float(grid.x) + 10.0 * mi.Float(grid.y)
    val, valid = K.reproject(grid, hist, mi.Vector2f(0.25, 0.5))
    val = np.array(val).reshape(h, w)
    ys, xs = np.indices((h, w))
    np.testing.assert_allclose(val[1:, 1:], ((xs - 0.25) + 10 * (ys - 0.5))[1:, 1:], atol=1e-5)
    np.testing.assert_allclose(val[0, 1:], xs[0, 1:] - 0.25, atol=1e-6)  # clamp-to-edge row
    assert np.all(np.array(valid))


def test_closest_depth_velocity():
    h, w = 5, 5
    depth = np.full((h, w), 10.0, F)
    depth[1, 2] = 2.0                       # closest in the centre's 3x3
    motion = np.zeros((h, w, 2), F)
    motion[1, 2] = (1.0, -2.0)
    motion[0, 0] = (7.0, 7.0)               # equal-depth tie: row-major first wins
    fr = dict(color=np.full((h, w, 3), 0.5, F), depth=depth, motion=motion)
    t = taa_impl.make("taa_baseline")
    t.process(fr, jitter=(0, 0), far=100.0)
    vel = t.debug_terms()["velocity"]
    np.testing.assert_array_equal(vel[2, 2], [1.0, -2.0])
    np.testing.assert_array_equal(vel[1, 1], [1.0, -2.0])
    np.testing.assert_array_equal(vel[4, 4], [0.0, 0.0])
    np.testing.assert_array_equal(vel[0, 0], [7.0, 7.0])   # (0,0) ties with its clamped copies
    np.testing.assert_array_equal(vel[1, 0], [7.0, 7.0])   # first tap (-1,-1) clamps to (0,0)


def test_first_frame_is_sharpened_current_and_history_is_current():
    c = np.ones((5, 5, 3), F)
    c[2, 2] = 2.0
    for sharpen, centre, cross in (("xu", 6.0, 0.0), ("normalised", 3.0, 0.75), ("none", 2.0, 1.0)):
        t = taa_impl.make("taa_baseline", sharpen=sharpen)
        out = t.process(still_frame(c), jitter=(0, 0), far=100.0)
        assert np.all(out[2, 2] == centre) and np.all(out[1, 2] == cross) and np.all(out[0, 0] == 1.0)
        np.testing.assert_array_equal(t.history, c)  # the history is the unsharpened blend


# -------------------------------------------------------------------- thesis worked examples
@pytest.mark.parametrize("ids,expected", [
    ([[3, 3, 3], [3, 3, 3], [5, 23, 82]], 3 / 9),
    ([[3, 3, 3], [3, 5, 3], [5, 23, 82]], 7 / 9),
])
def test_model_average_worked_examples(ids, expected):
    t = taa_impl.make("taa_improved")
    t.process(still_frame(np.full((3, 3, 3), 0.5, F), ids=ids), jitter=(0, 0), far=100.0)
    terms = t.debug_terms()
    assert terms["modelAverage"][1, 1] == pytest.approx(expected, abs=1e-7)
    # constant colour, albedo and depth: no Sobel, no depth term, so aliasedValue = modelAverage
    assert terms["aliasedValue"][1, 1] == pytest.approx(expected, abs=1e-7)


DEPTHS = [[9.0, 9.3, 8.7], [9.2, 9.0, 9.3], [8.8, 8.9, 8.7]]


def _depth_terms(depth, far, prev=None):
    t = taa_impl.make("taa_improved")
    fr = still_frame(np.full((3, 3, 3), 0.5, F), depth=depth)
    if prev is not None:
        fr["prev_depth"] = np.asarray(prev, F)
    t.process(fr, jitter=(0, 0), far=far)
    return {k: v[1, 1] for k, v in t.debug_terms().items()}


def test_depth_pseudo_variance_worked_examples():
    # The thesis's depths look like world units; its 0.002 threshold is in z/far. For its two
    # spatial examples to come out as it says, maxDepthDistance (0.2889 resp. 0.8667 world units)
    # must straddle 0.002*far: 144.4 < far <= 433.3. We use far = 200.
    flat = _depth_terms(DEPTHS, far=200.0)
    assert flat["maxDepthDistance"] == pytest.approx((8.988889 - 8.7) / 200, rel=1e-4)
    assert flat["depthPV"] == 0.0 and flat["depthTPV"] == 0.0
    assert flat["aliasedValue"] < 0.05          # only the (tiny) depth Sobel remains
    hole = [row[:] for row in DEPTHS]
    hole[1][1] = 4.0
    spike = _depth_terms(hole, far=200.0)
    assert spike["depthPV"] == pytest.approx((4.433333 / 0.866667) ** 2, rel=1e-4)  # 26.17
    assert spike["aliasedValue"] == 1.0


def test_depth_temporal_example_needs_a_smaller_far():
    # The thesis's third example (matrix 4.7 whose centre was 4.0 last frame is aliased) contradicts
    # the gate at far = 200 (the gate zeroes depthTPV too); at far = 100 the gate is open:
    prev = [row[:] for row in DEPTHS]
    prev[1][1] = 4.0
    gated = _depth_terms(DEPTHS, far=200.0, prev=prev)
    assert gated["depthTPV"] == 0.0
    open_ = _depth_terms(DEPTHS, far=100.0, prev=prev)
    mdd = 8.988889 - 8.7
    assert open_["depthPV"] == pytest.approx((0.011111 / mdd) ** 2, rel=1e-3)   # 0.0015: small
    assert open_["depthTPV"] == pytest.approx((4.988889 / mdd) ** 4, rel=1e-3)  # 8.9e4
    assert open_["aliasedValue"] == 1.0


def test_sobel_of_a_step_edge():
    c = np.zeros((4, 6, 3), F)
    c[:, 3:] = 1.0                          # Rec.709 luminance 0 | 1
    t = taa_impl.make("taa_improved")
    t.process(still_frame(c), jitter=(0, 0), far=100.0)
    s = t.debug_terms()["sobel_raw"]
    # |Gx| = 4 on both sides of the edge: g = clamp01(0.7 * 4) = 1 -> sobel = 1
    assert s[1, 2] == pytest.approx(1.0) and s[1, 3] == pytest.approx(1.0)
    assert s[1, 0] == 0.0 and s[1, 5] == 0.0
    c2 = c * 0.25                           # |Gx| = 1 -> g = 0.7 -> sqrt(0.49 * 1.6)
    t.process(still_frame(c2), jitter=(0, 0), far=100.0, reset=True)
    assert t.debug_terms()["sobel_raw"][1, 2] == pytest.approx(np.sqrt(0.49 * 1.6), rel=1e-6)


# ------------------------------------------------------------------------------- behaviour
@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("sharpen", ["xu", "normalised", "none"])
def test_constant_image_stays_exactly_constant(name, sharpen):
    rng = np.random.default_rng(3)
    h, w = 16, 24
    c = np.empty((h, w, 3), F)
    c[:] = (0.1234567, 3.3333333, 0.7)
    t = taa_impl.make(name, sharpen=sharpen)
    for i in range(20):
        fr = still_frame(c, depth=rng.uniform(1, 90, (h, w)), ids=rng.integers(0, 4, (h, w)),
                         albedo=rng.random((h, w, 3)))
        fr["motion"] = rng.normal(0, 3, (h, w, 2)).astype(F)
        out = t.process(fr, jitter=(rng.uniform(-.5, .5), rng.uniform(-.5, .5)), far=100.0)
        assert np.array_equal(out, c), f"frame {i}"


@pytest.mark.parametrize("name", NAMES)
def test_still_scene_converges_to_mean_of_16_values(name):
    # Columns B A C B A C ...: B = 0, C = 1 (constant) keep every A pixel's box at [0, 1], so the
    # history of A is never clipped. The 16 values of A share one feedback luminance (0.25, 0.5,
    # 0.25), so k = k_max exactly and A's output is the EMA y_n = x_n + k (y_{n-1} - x_n).
    h, w, n = 4, 9, 320
    rng = np.random.default_rng(7)
    t16 = rng.uniform(-0.3, 0.3, 16)
    vals = np.stack([0.5 + t16, np.full(16, 0.5), 0.5 - t16], axis=1).astype(F)
    mu = vals.astype(np.float64).mean(axis=0)
    tech = taa_impl.make(name, feedback="inside", sharpen="none")
    k = tech.params.k_max
    outs = []
    for i in range(n):
        c = np.zeros((h, w, 3), F)
        c[:, 2::3] = 1.0
        c[:, 1::3] = vals[i % 16]
        outs.append(tech.process(still_frame(c), jitter=(0, 0), far=100.0)[:, 1::3])
    outs = np.array(outs, np.float64)                       # (n, h, 3, 3)
    assert np.all(outs == outs[:, :1, :1])                  # every A pixel identical
    y = outs[:, 0, 0]
    # exact EMA prediction
    ema = np.empty((n, 3))
    ema[0] = vals[0]
    for i in range(1, n):
        ema[i] = vals[i % 16] + k * (ema[i - 1] - vals[i % 16])
    np.testing.assert_allclose(y, ema, atol=2e-5)
    # convergence to the mean: over one period the steady state averages to mu exactly; the
    # transient is at most k^(n-16) * max|x - mu| (plus float32 rounding)
    spread = np.abs(vals - mu).max()
    tol = k ** (n - 16) * spread + 2e-5
    np.testing.assert_allclose(y[-16:].mean(axis=0), mu, atol=tol)
    # every frame lies within the steady-state ripple around mu
    x = vals.astype(np.float64) - mu
    ripple = max(np.abs(sum((1 - k) * k ** j * x[(m - j) % 16] for j in range(16)) / (1 - k ** 16)).max()
                 for m in range(16))
    assert np.all(np.abs(y[-16:] - mu) <= ripple + tol)
    assert ripple < spread / 2                              # the bound is meaningful
    assert tol < 1e-3


@pytest.mark.parametrize("name", NAMES)
def test_zero_size_box_gives_no_nan(name):
    h, w = 8, 8
    t = taa_impl.make(name, sharpen="none")
    t.process(still_frame(np.full((h, w, 3), 0.2, F)), jitter=(0, 0), far=100.0)
    for value in (0.7, 1e4, 0.0, 0.0):
        out = t.process(still_frame(np.full((h, w, 3), value, F)), jitter=(0, 0), far=100.0)
        assert np.all(np.isfinite(out))
        np.testing.assert_allclose(out, value, atol=1e-7 + 1e-7 * value)  # clipped onto the point


NONFINITE = [("color", np.nan), ("color", np.inf), ("color", -np.inf), ("depth", np.inf),
             ("motion", np.nan), ("albedo", np.nan), ("prev_depth", np.inf)]


@pytest.mark.parametrize("name,buffer,value", [
    (n, b, v) for n in NAMES for b, v in NONFINITE if b in taa_impl.TECHNIQUES[n].needs])
def test_single_nonfinite_pixel_does_not_survive(name, buffer, value):
    tech = taa_impl.make(name)
    frames = random_frames(seed=11, n=6)
    bad = [dict(fr) for fr in frames]
    bad[2] = {k: v.copy() for k, v in frames[2].items()}
    bad[2][buffer][5, 7] = value
    outs = run(tech, bad)
    for i, out in enumerate(outs):
        assert np.all(np.isfinite(out)), f"frame {i}"
    assert np.all(np.isfinite(tech.history))
    # the count is reported on the frame that had it, for that buffer, and on no other frame
    tech2 = taa_impl.make(name)
    seen = []
    for i, fr in enumerate(bad):
        tech2.process(fr, jitter=(0, 0), far=100.0)
        seen.append(tech2.last_nonfinite_count)
        if i == 2:
            assert tech2.last_nonfinite[buffer] == 1
    assert seen == [0, 0, 1, 0, 0, 0]
    # it does not spread: on that frame only a small window around it differs from a clean run
    # (radius 4 = Sobel 1 + Sobel-TAA box 1 + Sobel means 1 + sharpen 1)
    clean = run(taa_impl.make(name), frames)
    far_away = np.ones(outs[2].shape[:2], bool)
    far_away[5 - 4:5 + 5, 7 - 4:7 + 5] = False
    np.testing.assert_array_equal(outs[2][far_away], clean[2][far_away])
    if buffer == "color":
        # repaired as the mean of the 8 neighbours: identical to feeding that mean in
        fixed = [dict(fr) for fr in frames]
        fixed[2] = {k: v.copy() for k, v in frames[2].items()}
        nb = frames[2]["color"][4:7, 6:9].reshape(9, 3)
        fixed[2]["color"][5, 7] = np.delete(nb, 4, axis=0).sum(axis=0) / F(8)
        ref = run(taa_impl.make(name), fixed)
        for a, b in zip(outs, ref):
            np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("sharpen", ["xu", "normalised"])
def test_hdr_edge_gives_no_negative_or_nan(name, sharpen):
    h, w = 12, 16
    rng = np.random.default_rng(5)
    tech = taa_impl.make(name, sharpen=sharpen)
    for i in range(12):
        c = np.full((h, w, 3), 1e-3, F)
        edge = 8 + (i % 3) - 1                                   # the edge moves by a pixel
        c[:, :edge] = 1e4
        fr = still_frame(c, depth=np.where(np.arange(w) < edge, 5.0, 50.0)[None].repeat(h, 0),
                         ids=np.where(np.arange(w) < edge, 1, 2)[None].repeat(h, 0))
        fr["motion"] = rng.uniform(-0.7, 0.7, (h, w, 2)).astype(F)
        out = tech.process(fr, jitter=(rng.uniform(-.5, .5), rng.uniform(-.5, .5)), far=100.0)
        assert np.all(np.isfinite(out)) and np.all(out >= 0)
        hist = tech.history
        assert hist.min() >= 1e-3 * (1 - 1e-5) and hist.max() <= 1e4 * (1 + 1e-5)
    if sharpen == "xu":
        assert np.any(out == 0.0)  # Xu's kernel undershoots next to the edge: clamped, not negative


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("velocity", [(25.0, 0.0), (0.0, -17.0), (1e6, -1e6), (-3e9, 2.0)])
def test_velocity_beyond_screen_gives_current_colour(name, velocity):
    h, w = 16, 24
    frames = random_frames(seed=2, n=3, h=h, w=w)
    tech = taa_impl.make(name, sharpen="none")
    tech.process(frames[0], jitter=(0, 0), far=100.0)
    fr = dict(frames[1])
    fr["motion"] = np.broadcast_to(np.array(velocity, F), (h, w, 2)).copy()
    out = tech.process(fr, jitter=(0, 0), far=100.0)
    np.testing.assert_array_equal(out, np.maximum(fr["color"], 0))
    assert np.all(tech.debug_terms()["history_valid"] == 0)


# ----------------------------------------------------------------------- determinism, state
@pytest.mark.parametrize("name", NAMES)
def test_deterministic_reset_and_resolution_change(name):
    frames = random_frames(seed=4, n=5)
    a, b = run(taa_impl.make(name), frames), run(taa_impl.make(name), frames)
    for x, y in zip(a, b):
        assert np.array_equal(x, y)
    t = taa_impl.make(name)
    run(t, frames[:3])
    again = t.process(frames[0], jitter=(0, 0), far=100.0, reset=True)
    assert np.array_equal(again, a[0])
    t.reset()
    assert t.history is None
    small = random_frames(seed=9, n=1, h=8, w=12)[0]
    run(t, frames[:2])
    assert np.array_equal(t.process(small, jitter=(0, 0), far=100.0),
                          taa_impl.make(name).process(small, jitter=(0, 0), far=100.0))

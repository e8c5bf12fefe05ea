"""Sparse-supersampling TAA (Li, Chen, Zhang 2021, taa_impl/sparse.py): the reuse test, the composite, the
driver protocol (invalid_mask -> supersampled -> process) and the statistics."""
from __future__ import annotations

import numpy as np
import pytest

import backend  # noqa: F401  (before anything touches drjit)
from backend import dr, mi

import taa_impl
from taa_impl.sparse import SparseTAA, colour_difference
from tests.test_taa import random_frames, still_frame

F = np.float32
FAR = 100.0


def drive(tech, frame, supersampled_of=None, reset=False, jitter=(0.0, 0.0)):
    """What study.engine.drive does: mask first, then render the supersampled colour there, then process.
    `supersampled_of(frame, mask)` stands in for the raster (default: a marker colour)."""
    mask = tech.invalid_mask(frame, far=FAR, reset=reset)
    ss = (np.full(frame["color"].shape, 7.0, F) if supersampled_of is None
          else np.asarray(supersampled_of(frame, mask), F))
    ss = np.where(mask[..., None], ss, F(0))           # the raster leaves 0 outside the mask
    out = tech.process(frame, jitter=jitter, far=FAR, reset=reset, supersampled=ss, mask=mask)
    return out, mask, ss


def test_registry_and_params():
    t = taa_impl.make("taa_sparse")
    assert isinstance(t, SparseTAA) and t.name == "taa_sparse"
    assert t.sampling == "sequence" and t.output_space == "linear" and t.inputs.masks is True
    assert (t.params.mu, t.params.samples, t.params.difference) == (0.2, 8, "tonemapped_max")
    assert t.needs == {"color", "depth", "motion"}
    assert hash(t.params) == hash(taa_impl.make("taa_sparse").params)
    assert taa_impl.make("taa_sparse", mu=float("inf")).params.mu == float("inf")
    for bad in ({"mu": -0.1}, {"mu": float("nan")}, {"samples": 0}, {"samples": 2.5},
                {"difference": "nope"}):
        with pytest.raises(ValueError):
            taa_impl.make("taa_sparse", **bad)


def test_first_frame_all_invalid_then_still_constant_scene_has_none():
    c = np.full((6, 7, 3), 0.4, F)
    t = taa_impl.make("taa_sparse", sharpen="none")
    out, mask, ss = drive(t, still_frame(c))
    assert mask.all()                                            # no history: all invalid
    np.testing.assert_array_equal(out, ss)                       # composite = supersampled
    np.testing.assert_array_equal(t.history, ss)                 # ... and it is the history
    assert t.last_stats == {"invalid_fraction": 1.0, "extra_samples": 42 * 8, "pixels": 42}
    # a history of the supersampled colour 0.4 from now on
    t2 = taa_impl.make("taa_sparse", sharpen="none")
    drive(t2, still_frame(c), lambda fr, m: fr["color"])
    for _ in range(3):
        out, mask, _ = drive(t2, still_frame(c), lambda fr, m: fr["color"])
        assert not mask.any()
        np.testing.assert_array_equal(out, c)
        assert t2.last_stats == {"invalid_fraction": 0.0, "extra_samples": 0, "pixels": 42}


def test_sudden_colour_change_marks_exactly_that_region():
    h, w = 10, 12
    c = np.full((h, w, 3), 0.5, F)
    t = taa_impl.make("taa_sparse", sharpen="none")
    for _ in range(4):
        drive(t, still_frame(c), lambda fr, m: fr["color"])
    region = np.zeros((h, w), bool)
    region[3:6, 4:9] = True
    c2 = c.copy()
    c2[region] = (0.05, 2.0, 0.05)           # green flash: |T(c) - T(h)| = 0.33 in G
    ss_colour = np.array([0.1, 1.8, 0.1], F)  # what 8 samples would give (a marker here)
    before = t.history.copy()
    out, mask, ss = drive(t, still_frame(c2), lambda fr, m: np.broadcast_to(ss_colour, fr["color"].shape))
    np.testing.assert_array_equal(mask, region)
    np.testing.assert_array_equal(out[region], np.broadcast_to(ss_colour, (region.sum(), 3)))
    np.testing.assert_array_equal(t.history[region], out[region])
    # elsewhere the baseline blend; far from the region the scene is unchanged: exactly 0.5
    far_px = np.ones((h, w), bool)
    far_px[1:8, 2:11] = False
    np.testing.assert_array_equal(out[far_px], before[far_px])
    n = int(region.sum())
    assert t.last_stats == {"invalid_fraction": n / (h * w), "extra_samples": n * 8, "pixels": h * w}
    assert t.debug_terms()["invalid"][region].min() == 1.0
    # the flash is shorter than mu in another formula: a linear difference of 1.5 > 0.2 also fires
    t_lin = taa_impl.make("taa_sparse", difference="linear_max", samples=4)
    for _ in range(2):
        drive(t_lin, still_frame(c), lambda fr, m: fr["color"])
    _, mask, _ = drive(t_lin, still_frame(c2))
    np.testing.assert_array_equal(mask, region)
    assert t_lin.last_stats["extra_samples"] == n * 4


def test_small_change_below_mu_is_valid_and_blended():
    c = np.full((5, 5, 3), 0.5, F)
    t = taa_impl.make("taa_sparse", sharpen="none")
    drive(t, still_frame(c), lambda fr, m: fr["color"])
    c2 = c.copy()
    c2[2, 2] = 0.8                             # T: 0.444 - 0.333 = 0.11 < 0.2
    _, mask, _ = drive(t, still_frame(c2))
    assert not mask.any()


def test_colour_difference_by_hand():
    # three pixels (mi.Color3f takes the R, G, B channels): c = (0,1,0), (3,1,0), (1,.2,.2)
    c = mi.Color3f([0.0, 3.0, 1.0], [1.0, 1.0, 0.2], [0.0, 0.0, 0.2])
    h = mi.Color3f([1.0, 1.0, 1.0], [1.0, 1.0, 0.1], [0.0, 0.0, 0.2])   # (1,1,0), (1,1,0), (1,.1,.2)
    tm = np.array(colour_difference("tonemapped_max", c, h))
    np.testing.assert_allclose(tm, [0.5, 0.75 - 0.5, 0.2 / 1.2 - 0.1 / 1.1], rtol=1e-6)
    lin = np.array(colour_difference("linear_max", c, h))
    np.testing.assert_allclose(lin, [1.0, 2.0, 0.1], rtol=1e-6)
    lum = lambda r, g, b: 0.2126 * r + 0.7152 * g + 0.0722 * b  # noqa: E731
    pairs = [((0, 1, 0), (1, 1, 0)), ((3, 1, 0), (1, 1, 0)), ((1, .2, .2), (1, .1, .2))]
    want = [abs(lum(*a) - lum(*b)) / max(lum(*a), lum(*b), 0.2) for a, b in pairs]
    np.testing.assert_allclose(np.array(colour_difference("luma_relative", c, h)), want, rtol=1e-5)
    # the floor: two dark colours
    d = np.array(colour_difference("luma_relative", mi.Color3f(0.0, 0.1, 0.0), mi.Color3f(0.0)))
    assert d[0] == pytest.approx(0.07152 / 0.2, rel=1e-5)


@pytest.mark.parametrize("overrides", [{}, {"feedback": "inside", "sharpen": "normalised",
                                            "history_filter": "catmull_rom"}])
def test_mu_inf_is_the_baseline_frame_by_frame(overrides):
    """With mu = inf only history-less pixels (first frame, off-screen, reset) are invalid; given
    their current colour as the 'supersampled' one, every frame equals BaselineTAA's bit for bit."""
    frames = random_frames(seed=11, n=6)
    s = taa_impl.make("taa_sparse", mu=float("inf"), **overrides)
    fields = taa_impl.TAAParams.__dataclass_fields__
    base_params = taa_impl.TAAParams(**{k: getattr(s.params, k) for k in fields})
    b = taa_impl.BaselineTAA(base_params)
    offscreen_seen = 0
    for i, fr in enumerate(frames):
        reset = i == 3
        jit = (0.25, -0.125)
        ref = b.process(fr, jitter=jit, far=FAR, reset=reset)
        out, mask, _ = drive(s, fr, lambda f, m: f["color"], reset=reset, jitter=jit)
        np.testing.assert_array_equal(out, ref, err_msg=f"frame {i}")
        np.testing.assert_array_equal(s.history, b.history)
        if i in (0, 3):
            assert mask.all()
        else:
            hv = b.debug_terms()["history_valid"] > 0
            np.testing.assert_array_equal(mask, ~hv)
            offscreen_seen += int(mask.sum())
    assert offscreen_seen > 0


def test_invalid_mask_changes_no_state_and_matches_process():
    frames = random_frames(seed=5, n=5)
    a = taa_impl.make("taa_sparse", reject_depth=0.05, reject_id=True)
    b = taa_impl.make("taa_sparse", reject_depth=0.05, reject_id=True)
    fractions = []
    for fr in frames:
        m1 = a.invalid_mask(fr, far=FAR)
        m2 = a.invalid_mask(fr, far=FAR)                  # asking twice changes nothing
        np.testing.assert_array_equal(m1, m2)
        ss = np.where(m1[..., None], F(0.25), np.zeros(fr["color"].shape, F))
        out_a = a.process(fr, jitter=(0, 0), far=FAR, supersampled=ss, mask=m1)
        out_b = b.process(fr, jitter=(0, 0), far=FAR, supersampled=ss)   # its own mask
        np.testing.assert_array_equal(out_a, out_b)
        assert a.last_stats == b.last_stats
        assert a.last_stats["invalid_fraction"] == pytest.approx(m1.mean())
        assert a.last_stats["extra_samples"] == int(m1.sum()) * 8
        fractions.append(m1.mean())
    assert 0 < min(fractions[1:]) and max(fractions[1:]) < 1   # noisy frames: some pixels of each


def test_protocol_errors_and_superset_mask():
    c = np.full((4, 5, 3), 0.5, F)
    t = taa_impl.make("taa_sparse", sharpen="none")
    with pytest.raises(ValueError, match="supersampled"):
        t.process(still_frame(c), jitter=(0, 0), far=FAR)
    with pytest.raises(ValueError, match="shape"):
        t.process(still_frame(c), jitter=(0, 0), far=FAR, supersampled=np.zeros((4, 4, 3), F))
    with pytest.raises(ValueError, match="misses"):   # first frame: every pixel is needed
        t.process(still_frame(c), jitter=(0, 0), far=FAR, supersampled=np.zeros_like(c),
                  mask=np.zeros((4, 5), bool))
    drive(t, still_frame(c), lambda fr, m: fr["color"])
    # a superset mask is fine: the driver rendered more; those pixels take the supersampled colour
    extra = np.zeros((4, 5), bool)
    extra[0, 0] = True
    out = t.process(still_frame(c), jitter=(0, 0), far=FAR,
                    supersampled=np.where(extra[..., None], F(0.9), np.zeros_like(c)), mask=extra)
    assert np.all(out[0, 0] == F(0.9)) and np.all(out[1:, 1:] == F(0.5))
    assert t.last_stats["extra_samples"] == 8
    # reset and a resolution change: all invalid again
    assert t.invalid_mask(still_frame(c), far=FAR, reset=True).all()
    assert t.invalid_mask(still_frame(np.full((3, 5, 3), 0.5, F)), far=FAR).all()
    # non-finite supersampled values inside the mask fall back to the current colour, counted
    t.reset()
    ss = np.full_like(c, 0.3)
    ss[1, 1] = np.nan
    out = t.process(still_frame(c), jitter=(0, 0), far=FAR, supersampled=ss)
    assert np.all(np.isfinite(t.history)) and np.all(out[1, 1] == F(0.5))
    assert t.last_nonfinite["supersampled"] == 1


def test_the_reuse_test_holds_at_mu_itself():
    # "if the inequality holds the reuse succeeds": D <= mu reuses the history, so a difference of
    # exactly mu (0.25 = 0.75 - 0.5, exact in float32) is valid and one just above it is not
    c = np.full((5, 5, 3), 0.5, F)
    t = taa_impl.make("taa_sparse", sharpen="none", difference="linear_max", mu=0.25)
    drive(t, still_frame(c), lambda fr, m: fr["color"])
    c2 = c.copy()
    c2[1, 1] = 0.75
    c2[3, 3] = 0.7578125
    _, mask, _ = drive(t, still_frame(c2))
    assert not mask[1, 1] and mask[3, 3]
    assert mask.sum() == 1

"""No AA, the accumulation buffer, the registry, how techniques are driven, and history resets."""
from __future__ import annotations

import numpy as np
import pytest

import backend  # noqa: F401  (before anything touches drjit)

import taa_impl
from taa_impl import ENCODED
from taa_impl.base import OUTPUT_SPACES, SAMPLING_MODES
from scenes.jitter import halton_offset
from tests.test_taa import random_frames

F = np.float32
ALL = ["noaa", "accumulation", "fxaa", "taa_baseline", "taa_improved", "taa_ycocg", "taa_variance",
       "taa_catmull_rom", "taa_tonemap_blend", "taa_reject", "taa_ycocg_variance"]


def call(tech, frame, **kw):
    return tech.process(frame, jitter=kw.pop("jitter", (0.0, 0.0)), far=100.0, display=ENCODED, **kw)


# ------------------------------------------------------------------------------ registry
def test_registry_names_and_driving_attributes():
    assert set(ALL) <= set(taa_impl.TECHNIQUES)
    expect = {"noaa": ("centre", "linear"), "accumulation": ("supersample", "linear"),
              "fxaa": ("centre", "display")}
    for name in ALL:
        t = taa_impl.make(name)
        assert t.name == name
        assert t.sampling in SAMPLING_MODES and t.output_space in OUTPUT_SPACES
        assert (t.sampling, t.output_space) == expect.get(name, ("sequence", "linear")), name
        assert t.needs >= {"color"}
        # the registry entry advertises the same as the instance (what a driver reads first)
        entry = taa_impl.TECHNIQUES[name]
        assert (entry.sampling, entry.output_space) == (t.sampling, t.output_space)
        assert hash(t.params) == hash(taa_impl.make(name).params)
    assert taa_impl.make("noaa").needs == {"color"}
    assert taa_impl.make("accumulation").needs == {"color"}
    assert taa_impl.make("fxaa").needs == {"color"}
    with pytest.raises(KeyError):
        taa_impl.make("smaa_typo")
    with pytest.raises(ValueError):
        taa_impl.make("accumulation", feedback="inside")   # a TAA-only preset
    with pytest.raises(TypeError, match="unknown parameter 'k_min' of NoAAParams"):
        taa_impl.make("noaa", k_min=0.5)                  # not a field of No AA


# ------------------------------------------------------------------------------- No AA
def test_noaa_returns_the_colour_as_is():
    fr = random_frames(seed=1, n=1, h=7, w=9)[0]
    t = taa_impl.make("noaa")
    for _ in range(2):
        out = call(t, fr)
        assert out.dtype == np.float32 and np.array_equal(out, fr["color"])
    hdr = {"color": np.full((3, 4, 3), 1e4, F)}
    hdr["color"][1, 2] = (-0.5, 0.0, 7.0)           # no clamping either: the sample as is
    assert np.array_equal(call(t, hdr), hdr["color"])
    bad = {"color": hdr["color"].copy()}
    bad["color"][0, 0, 1] = np.nan
    out = call(t, bad)
    assert np.all(np.isfinite(out)) and t.last_nonfinite_count == 1


# --------------------------------------------------------------------------- accumulation
def test_accumulation_params():
    assert taa_impl.make("accumulation").params.samples == 128
    assert taa_impl.make("accumulation", samples=16).params.samples == 16
    assert taa_impl.make("accumulation", samples=1000).params.samples == 1000
    for bad in (0, -3, 2.5, True):
        with pytest.raises(ValueError):
            taa_impl.make("accumulation", samples=bad)


def test_accumulation_of_constant_frames_is_the_constant():
    c = np.empty((5, 6, 3), F)
    c[:] = (0.1234567, 3.3333333, 1e4 / 3)
    t = taa_impl.make("accumulation", samples=128)
    frames = [{"color": c.copy()} for _ in range(128)]
    out = t.process(samples=frames, far=1.0)
    assert np.array_equal(out, c) and t.count == 128
    # one at a time: every running mean is the constant too
    t.reset()
    for i in range(37):
        assert np.array_equal(call(t, frames[i]), c)


def test_accumulation_equals_numpy_mean():
    rng = np.random.default_rng(3)
    n = 128
    cols = rng.uniform(0, 2, (n, 6, 8, 3)).astype(F)
    cols[:, 0, 0] *= 1e3                                 # HDR
    t = taa_impl.make("accumulation", samples=n)
    out = t.process(samples=[{"color": c} for c in cols], far=1.0)
    np.testing.assert_allclose(out, cols.astype(np.float64).mean(axis=0), rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(t.mean, out)
    # the running mean after k frames is the mean of the first k
    t.reset()
    assert t.mean is None
    for k in range(1, 20):
        out = call(t, {"color": cols[k - 1]})
        np.testing.assert_allclose(out, cols[:k].astype(np.float64).mean(axis=0), rtol=1e-6, atol=1e-6)
    # a frame of samples restarts the mean (it does not add to the running one)
    out = t.process(samples=[{"color": c} for c in cols[:4]], far=1.0)
    np.testing.assert_allclose(out, cols[:4].astype(np.float64).mean(axis=0), rtol=1e-6, atol=1e-6)
    assert t.count == 4


def test_accumulation_converges_to_the_pixel_area_mean_of_an_edge():
    # a vertical edge at x = 2.3 (left 1, right 0) sampled at Halton jitters: pixel 2's mean
    # converges to its covered fraction 0.3 (Halton(2) is exact for dyadic counts: 128 -> within 1/128)
    n = 128
    frames = []
    for j in range(n):
        ox, _ = halton_offset(j, n)
        xs = np.arange(5) + 0.5 + ox
        col = np.where(xs < 2.3, 1.0, 0.0).astype(F)
        frames.append({"color": np.broadcast_to(col[None, :, None], (2, 5, 3)).copy()})
    out = taa_impl.make("accumulation", samples=n).process(samples=frames, far=1.0)
    np.testing.assert_array_equal(out[:, :2], 1.0)
    np.testing.assert_array_equal(out[:, 3:], 0.0)
    assert abs(out[0, 2, 0] - 0.3) <= 1 / n


def test_accumulation_validates_and_counts_nonfinite():
    t = taa_impl.make("accumulation")
    with pytest.raises(ValueError):
        t.process(samples=[], far=1.0)
    with pytest.raises(ValueError):
        t.process(samples=[{"color": np.zeros((4, 4, 3), F)}, {"color": np.zeros((4, 5, 3), F)}], far=1.0)
    frames = [{"color": np.ones((4, 4, 3), F)} for _ in range(4)]
    frames[1]["color"][2, 2, 0] = np.inf
    frames[3]["color"][0, 1, 2] = np.nan
    out = t.process(samples=frames, far=1.0)
    assert np.all(np.isfinite(out)) and t.last_nonfinite_count == 2
    np.testing.assert_array_equal(out, 1.0)   # each repaired from its (all-1) neighbours


# ------------------------------------------------------------------ resets, for every technique
@pytest.mark.parametrize("name", ALL)
def test_reset_and_resolution_change_restart_the_history(name):
    frames = random_frames(seed=6, n=4, h=8, w=10)
    for fr in frames:
        fr["color"] = np.clip(fr["color"], 0, 1)       # FXAA's pass-through display
    fresh = call(taa_impl.make(name), frames[0])
    t = taa_impl.make(name)
    for fr in frames[1:]:
        call(t, fr)
    # camera cut: reset=True forgets everything before this frame
    assert np.array_equal(call(t, frames[0], reset=True), fresh)
    # explicit reset()
    call(t, frames[2])
    t.reset()
    assert np.array_equal(call(t, frames[0]), fresh)
    # resolution change: a new history at the new size, as if fresh
    small = random_frames(seed=7, n=1, h=6, w=7)[0]
    small["color"] = np.clip(small["color"], 0, 1)
    call(t, frames[1])
    assert np.array_equal(call(t, small), call(taa_impl.make(name), small))
    if name == "accumulation":
        assert t.count == 1


def test_stateful_techniques_do_carry_history():
    # (so that the reset test above tests something) the second output differs from a fresh one
    frames = random_frames(seed=6, n=2, h=8, w=10)
    for name in ("accumulation", "taa_baseline", "taa_improved", "taa_reject", "taa_ycocg_variance"):
        t = taa_impl.make(name)
        call(t, frames[0])
        assert not np.array_equal(call(t, frames[1]), call(taa_impl.make(name), frames[1])), name
    for name in ("noaa", "fxaa"):
        t = taa_impl.make(name)
        a = np.clip(frames[0]["color"], 0, 1)
        b = np.clip(frames[1]["color"], 0, 1)
        call(t, {"color": a})
        assert np.array_equal(call(t, {"color": b}), call(taa_impl.make(name), {"color": b}))

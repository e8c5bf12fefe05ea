"""The TAA clip is well conditioned in float32 (INSIDE's epsilon of 1e-8 rounds
m above 1 on a box face; taa_impl.kernels.clip_toward_centre), and the displayed output's clamp
at 0 is what the docs say.

The sequence test runs the float64 NumPy oracle on its own history and the Dr.Jit float32 kernels
on theirs over the ghosting schedule of four hard scenes. With INSIDE's clip (clip_tol=0) they
drifted apart by up to 8.8e-3 of the peak at 64x36 (2e-1 at 48x27, 8.8e-2 at 96x54, 16 frames),
first at fast_object, baseline TAA; with the tolerance the largest drift is 2e-5 of the peak
(scripts/taa_clip_drift.py prints both)."""
from __future__ import annotations

import numpy as np
import pytest

import backend  # noqa: F401  (before anything touches drjit)
from backend import dr, mi

import taa_impl
from taa_impl import kernels as K
from tests import oracle_taa as O
from tests.oracle_taa import OracleTAA

SCENES = ("fast_object", "camera_cut", "disocclusion", "hdr_contrast")
BUFS = ("color", "albedo", "depth", "object_id", "motion", "prev_depth")
W, H, FRAMES = 64, 36, 16   # camera_cut cuts at frame 12
TOL = 1e-4   # TAAParams.clip_tol's default, repeated so the hand cases below stay hand cases


@pytest.fixture(scope="module")
def sequences():
    """scene -> (frames, resets, far): the ghosting schedule (study.config.protocols.ghosting_schedule):
    step t shows scene time t with jitter halton_offset(t, 16), motion from t - 1, and the history
    is reset at t = 0 and at camera cuts."""
    from raster import Rasterizer
    from scenes import get_scene
    from scenes.jitter import halton_offset
    out = {}
    for name in SCENES:
        scene = get_scene(name)
        r = Rasterizer(scene, W, H)
        try:
            frames = [r.render(t, halton_offset(t, 16), BUFS, prev_t=t - 1) for t in range(FRAMES)]
        finally:
            r.close()
        out[name] = (frames, [scene.is_cut(t) for t in range(FRAMES)], float(scene.desc.camera.far))
    assert any(out["camera_cut"][1][1:])   # the cut lies inside the sequence
    return out


@pytest.mark.parametrize("name", ["taa_baseline", "taa_improved"])
@pytest.mark.parametrize("scene", SCENES)
def test_float32_kernels_follow_the_float64_oracle_over_a_sequence(sequences, scene, name):
    from scenes.jitter import halton_offset
    frames, resets, far = sequences[scene]
    tech = taa_impl.make(name)
    oracle = OracleTAA(tech.params, improved=name == "taa_improved", dtype=np.float64)
    clipped = 0
    for t, (fr, reset) in enumerate(zip(frames, resets)):
        out = tech.process(fr, jitter=halton_offset(t, 16), far=far, reset=reset)
        ref = oracle.process(fr, far=far, reset=reset)
        assert ref.dtype == np.float64 and oracle.history.dtype == np.float64
        peak = float(np.abs(fr["color"]).max())
        for what, a, b in (("output", out, ref), ("history", tech.history, oracle.history)):
            d = np.abs(a.astype(np.float64) - b)
            worst = np.unravel_index(int(np.argmax(d)), d.shape)
            assert d.max() <= 1e-3 * peak, (f"{scene} {name} t={t} {what} at (y, x, ch) {worst}: "
                                            f"{a[worst]} vs {b[worst]}, peak {peak}")
        if t > 0 and not reset:
            clipped += int(np.sum(np.abs(tech.debug_terms()["blend"] - fr["color"]) > 0))
    assert clipped > 0   # the history was used


# ------------------------------------------------------------------------- the clip by hand
def clip(h, lo, hi, eps=1e-8, tol=TOL):
    """The Dr.Jit clip on single colours, and the float64 oracle's, as NumPy arrays."""
    col = (lambda v: mi.Color3f(*(float(x) for x in v)))
    got = np.array(dr.ravel(K.clip_toward_centre(col(h), col(lo), col(hi), eps, tol)), np.float64)
    ref = O.clip_toward_centre(np.array(h, np.float64), np.array(lo, np.float64),
                               np.array(hi, np.float64), eps, tol)
    return got, ref


def test_rounding_in_a_zero_width_channel_does_not_drag_the_others():
    # G's box has zero width; the history is off it by 6e-8 (one float32 ulp at 0.5 is 6e-8).
    h, lo, hi = (0.9, np.float32(0.5) + np.float32(6e-8), 0.5), (0.0, 0.5, 0.5), (1.0, 0.5, 0.5)
    got, ref = clip(h, lo, hi)
    # m_G = 6e-8 / tau, tau = 1e-4 (0.5 + 0.5) + 1e-8: far below 1; m_R = 0.4 / (0.5 + tau) < 1:
    # no clip; the clamp puts G back on its box. R keeps 0.9 exactly.
    np.testing.assert_array_equal(got, np.array([0.9, 0.5, 0.5], np.float32))
    np.testing.assert_allclose(ref, [0.9, 0.5, 0.5], rtol=0, atol=1e-12)
    # INSIDE's clip (tol 0): m = 6e-8 / 1e-8 ~ 6, R dragged to 0.5 + 0.4 / m ~ 0.567
    inside, _ = clip(h, lo, hi, tol=0.0)
    assert 0.55 < inside[0] < 0.6


def test_a_real_offset_in_a_zero_width_channel_clips_as_inside():
    # G off its zero-width box by 0.1, a real colour difference: pulled almost onto the centre.
    got, ref = clip((0.9, 0.6, 0.5), (0.0, 0.5, 0.5), (1.0, 0.5, 0.5))
    tau = 1e-8 + 1e-4 * (0.5 + 0.5)
    m = 0.1 / tau                               # G drives: ~1000
    expect = [0.5 + 0.4 / m, 0.5, 0.5]          # then G clamped from 0.5 + tau to 0.5
    np.testing.assert_allclose(got, expect, rtol=0, atol=2e-7)
    np.testing.assert_allclose(ref, expect, rtol=0, atol=1e-12)


@pytest.mark.parametrize("scale", [1.0, 1e3, 1e-3])
def test_on_a_face_within_rounding_is_not_clipped_and_the_tolerance_scales(scale):
    lo, hi = np.array([0.1, 0.1, 0.1]) * scale, np.array([0.3, 0.3, 0.3]) * scale
    r_face = np.nextafter(np.float32(0.3 * scale), np.float32(1e9))   # one ulp outside the face
    h = (r_face, np.float32(0.2 * scale), np.float32(0.15 * scale))
    got, ref = clip(h, lo, hi)
    f32 = np.array([0.3 * scale, 0.2 * scale, 0.15 * scale], np.float32)
    np.testing.assert_array_equal(got, f32)        # G, B untouched, R clamped onto its face
    np.testing.assert_allclose(ref, f32, rtol=1e-7)
    # outside by more than tau (1e-4 * (0.2 + 0.1) relative): clipped along the ray to the face
    got, ref = clip((0.5 * scale, 0.2 * scale, 0.1 * scale), lo, hi)
    tau = 1e-8 + 1e-4 * 0.3 * scale
    m = 0.3 * scale / (0.1 * scale + tau)                 # R drives
    expect = [0.3 * scale, 0.2 * scale, 0.2 * scale - 0.1 * scale / m]   # R: clamped from p + e
    np.testing.assert_allclose(got, expect, rtol=1e-6)
    np.testing.assert_allclose(ref, expect, rtol=1e-12)


def test_far_outside_lands_on_the_box_and_inside_is_untouched():
    got, ref = clip((2.0, 0.5, 0.5), (0, 0, 0), (1, 1, 1))
    np.testing.assert_array_equal(got, [1.0, 0.5, 0.5])
    np.testing.assert_allclose(ref, [1.0, 0.5, 0.5], atol=1e-12)
    got, ref = clip((0.9, 0.1, 0.5), (0, 0, 0), (1, 1, 1))
    np.testing.assert_array_equal(got, np.array([0.9, 0.1, 0.5], np.float32))
    # a zero-size box at 0: tau = eps, finite, onto the point
    got, ref = clip((1e4, 0.0, -3.0), (0, 0, 0), (0, 0, 0))
    np.testing.assert_array_equal(got, [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(ref, [0.0, 0.0, 0.0])


def test_clip_on_random_boxes_matches_the_oracle():
    # degenerate channels included; Dr.Jit float32 against the float64 oracle on float32 inputs
    rng = np.random.default_rng(4)
    n = 4000
    lo = rng.uniform(0, 2, (n, 3)).astype(np.float32)
    hi = (lo + rng.uniform(0, 1, (n, 3)) * (rng.random((n, 3)) < 0.7)).astype(np.float32)
    h = (lo + rng.uniform(-1, 2, (n, 3)) * (hi - lo + 0.3)).astype(np.float32)
    col = (lambda a: dr.unravel(mi.Color3f, mi.Float(a.reshape(-1))))
    got = np.array(dr.ravel(K.clip_toward_centre(col(h), col(lo), col(hi), 1e-8, TOL))).reshape(n, 3)
    ref = O.clip_toward_centre(h.astype(np.float64), lo.astype(np.float64), hi.astype(np.float64), 1e-8, TOL)
    np.testing.assert_allclose(got, ref, rtol=0, atol=2e-6)
    assert np.all((got >= lo) & (got <= hi))
    assert np.mean(np.any(np.abs(got - h) > 1e-3, axis=1)) > 0.3   # most were clipped


def test_params_refuse_a_bad_tolerance():
    for bad in (-1e-4, 1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="clip_tol"):
            taa_impl.make("taa_baseline", clip_tol=bad)
    assert taa_impl.make("taa_baseline", clip_tol=0.0).params.clip_tol == 0.0   # INSIDE's clip


# ------------------------------------------------------------------------ the output clamp
@pytest.mark.parametrize("sharpen,w", [("xu", 1.0), ("normalised", 0.25)])
def test_displayed_output_is_the_sharpened_history_clamped_at_zero(sequences, sharpen, w):
    """The history is the unsharpened blend, inside the neighbourhood's range (so >= 0); the
    displayed output is max(sharpen(history), 0). On hdr_contrast (1000 next to ~0) the unclamped
    sharpen undershoots to -4 (Xu) resp. -1 (normalised) times the peak: the clamp is active."""
    from scenes.jitter import halton_offset
    frames, resets, far = sequences["hdr_contrast"]
    tech = taa_impl.make("taa_baseline", sharpen=sharpen)
    lowest = 0.0
    for t, (fr, reset) in enumerate(zip(frames, resets)):
        out = tech.process(fr, jitter=halton_offset(t, 16), far=far, reset=reset)
        hist = tech.history.astype(np.float64)
        assert hist.min() >= 0.0 and hist.max() <= fr["color"].max()
        kernel = [[0, -w, 0], [-w, 1 + 4 * w, -w], [0, -w, 0]]
        raw = O.convolve3x3(hist, kernel)
        np.testing.assert_allclose(out, np.maximum(raw, 0.0), rtol=1e-6, atol=1e-6 * fr["color"].max())
        lowest = min(lowest, raw.min() / fr["color"].max())
    assert lowest < -0.9 * (4 * w)

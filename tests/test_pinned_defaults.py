"""Pins of the defaults the study's tables depend on, each against a value
computed independently of the code: the published numbers (the thesis's, INSIDE's, Reinhard's) written as literals, and outputs worked out
by hand (the arithmetic is in the comments). A changed default fails here even when every other
test still passes. (SSIM's sigma is pinned in the metrics tests.)"""
from __future__ import annotations

import numpy as np
import pytest

import backend  # noqa: F401
import taa_impl
from display import KEY_PRESETS, DisplayTransform
from scenes.jitter import TAA_PERIOD, halton_offset
from taa_impl import kernels as K
from taa_impl.base import FEEDBACK_PRESETS, SHARPEN_KERNELS, TAAParams, sharpen_weight
from taa_impl.improved import ImprovedParams

F = np.float32


# --------------------------------------------------------------------- display (Reinhard 2002)
def test_reinhard_with_default_arguments_by_hand():
    # Reference, 1x3 pixels: white (L = 1), green 0.5 (L = 0.7152 * 0.5 = 0.3576), black (L = 0).
    # delta = 1e-4: L_avg = exp((ln 1.0001 + ln 0.3577 + ln 0.0001) / 3) = 0.03294990..., kept to
    # 3 significant digits: 0.0329 (the reference's noise cannot move a rounded exposure).
    # key 0.18: L_white = 0.18 / L_avg * max L = 5.4711 -> 5.47 (scaled units)
    ref = np.array([[[1.0, 1.0, 1.0], [0.0, 0.5, 0.0], [0.0, 0.0, 0.0]]], np.float32)
    dt = DisplayTransform.from_reference(ref)
    assert dt.key == 0.18
    assert dt.log_average == 0.0329
    assert dt.white == 5.47
    # The brightest pixel maps to 1: l = 5.4711, L_d = l (1 + l / W^2) / (1 + l) = 1.00006, clipped.
    # Green: l = 0.18 / L_avg * 0.3576 = 1.956474; L_d = l (1 + l / W^2) / (1 + l) = 0.7050305;
    # G = 0.5 * L_d / 0.3576 = 0.9857809260517499; sRGB 1.055 G^(1/2.4) - 0.055 = 0.9937234136117189.
    enc = dt.encode(ref)
    np.testing.assert_allclose(enc[0, 0], [1.0, 1.0, 1.0], rtol=1e-12)
    np.testing.assert_allclose(enc[0, 1], [0.0, 0.9937234136117189, 0.0], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(enc[0, 2], [0.0, 0.0, 0.0])
    # A technique's grey 0.2 under the reference's transform: l = 0.18 / L_avg * 0.2 = 1.094225;
    # L_d = 0.5416043713945302; sRGB 0.7621216046446604 -> 8 bits round(194.34) = 194.
    # (key 0.2 would give 198; delta 1e-6 would give 236.)
    grey = np.full((1, 1, 3), 0.2, np.float32)
    np.testing.assert_allclose(dt.tonemap(grey)[0, 0], 0.5416043713945302, rtol=1e-7)
    np.testing.assert_allclose(dt.encode(grey)[0, 0], 0.7621216046446604, rtol=1e-7)
    assert np.all(dt.to_8bit(grey) == 194)
    assert np.array_equal(dt.to_8bit(ref)[0, :, 1], [255, 253, 0])


def test_display_key_presets_are_the_specs():
    assert KEY_PRESETS == {"low": 0.09, "default": 0.18, "high": 0.36}


# ------------------------------------------------------------------- TAA parameters (spec 3, 5, 6)
def test_baseline_taa_defaults_are_the_specs():
    p = TAAParams()
    assert (p.k_min, p.k_max) == (0.925, 0.979)                   # the thesis author's preset
    assert FEEDBACK_PRESETS == {"thesis": (0.925, 0.979), "inside": (0.88, 0.97)}
    assert p.feedback_luma == (0.25, 0.5, 0.25)                   # INSIDE's feedback luma
    assert p.feedback_floor == 0.2
    assert p.clip_eps == 1e-8                                     # INSIDE's FLT_EPS
    assert p.clip_tol == 1e-4                                     # kernels.clip_toward_centre
    assert p.sharpen == "xu"
    assert SHARPEN_KERNELS["xu"] == ((0, -1, 0), (-1, 5, -1), (0, -1, 0))
    assert SHARPEN_KERNELS["normalised"] == ((0, -.25, 0), (-.25, 2, -.25), (0, -.25, 0))
    assert (sharpen_weight("xu"), sharpen_weight("normalised")) == (1.0, 0.25)
    # extensions all off
    assert (p.box, p.variance_clip_gamma, p.history_filter, p.tonemap_blend, p.reject_depth,
            p.reject_id) == ("minmax", None, "bilinear", False, None, False)


def test_improved_taa_defaults_are_the_specs():
    p = ImprovedParams()
    assert (p.k_min, p.k_max, p.feedback_floor, p.feedback_luma) == (0.925, 0.979, 0.2, (0.25, 0.5, 0.25))
    assert p.sharpen == "normalised"                              # thesis eq. 4.13
    assert p.depth_threshold == 0.002                             # normalised depth z / far
    assert (p.sobel_weight_albedo, p.sobel_weight_color, p.sobel_weight_depth) == (0.3, 0.7, 1.0)
    assert p.sobel_luma == (0.2126, 0.7152, 0.0722)               # Rec.709
    assert K.REC709 == (0.2126, 0.7152, 0.0722)
    assert taa_impl.make("taa_improved").params == p


def test_taa_jitter_is_halton_2_3_from_index_1_with_period_16():
    assert TAA_PERIOD == 16
    # index k + 1 (0 skipped): base 2 of 1, 2, 3 = 1/2, 1/4, 3/4; base 3 = 1/3, 2/3, 1/9; minus 0.5
    expect = [(0.0, -1 / 6), (-0.25, 1 / 6), (0.25, 1 / 9 - 0.5)]
    for k, (x, y) in enumerate(expect):
        assert halton_offset(k) == pytest.approx((x, y), abs=1e-15)
        assert halton_offset(k + 16) == pytest.approx((x, y), abs=1e-15)


# ------------------------------------------------------------- a baseline TAA pixel by hand
def columns(a):
    """3x3 image, columns B | A | C: B = black, C = (0.2, 0.1, 0), A given (all rows alike)."""
    img = np.zeros((3, 3, 3), F)
    img[:, 1] = a
    img[:, 2] = (0.2, 0.1, 0.0)
    return img


@pytest.mark.parametrize("feedback,k", [
    # d = |l_c - l_h| / max(l_c, l_h, 0.2) = 0.05 / 0.2 = 0.25 (the floor decides), w = (1 - d)^2
    # = 0.5625, k = k_min + (k_max - k_min) w
    (None, 0.925 + 0.054 * 0.5625),       # default (thesis) preset: 0.955375
    ("inside", 0.88 + 0.09 * 0.5625),     # 0.930625
])
def test_baseline_taa_output_pixel_by_hand(feedback, k):
    # Frame 0: A = (0.2, 0.1, 0); frame 1: A = (0, 0.1, 0); still camera, zero motion.
    # Feedback luma (0.25, 0.5, 0.25): l_h = 0.05 + 0.05 = 0.1, l_c = 0.05 (Rec.709 would give
    # 0.114 and 0.0715). A's box (3x3 and cross both span B, A, C) is R [0, 0.2], G [0, 0.1],
    # B [0, 0]: the history (0.2, 0.1, 0) lies on it, so no clip. Blend A = c + k (h - c) =
    # (0.2 k, 0.1, 0). B and C are constant and stay exact. Xu's sharpen (the default):
    # out = a + sum(a - n) over up, down (both a), left (B = 0), right (C) = 3a - C.
    kw = {} if feedback is None else {"feedback": feedback}
    tech = taa_impl.make("taa_baseline", **kw)
    frame = {"depth": np.full((3, 3), 10.0, F), "motion": np.zeros((3, 3, 2), F)}
    tech.process(dict(frame, color=columns((0.2, 0.1, 0.0))), jitter=(0, 0), far=100.0)
    out = tech.process(dict(frame, color=columns((0.0, 0.1, 0.0))), jitter=(0, 0), far=100.0)
    blend_r = 0.2 * k
    np.testing.assert_allclose(tech.history[1, 1], [blend_r, 0.1, 0.0], rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(out[1, 1], [3 * blend_r - 0.2, 0.3 - 0.1, 0.0], rtol=1e-6, atol=1e-8)
    if feedback is None:
        # the same numbers written out: 0.191075 and 0.373225
        np.testing.assert_allclose(out[:, 1], [[0.373225, 0.2, 0.0]] * 3, rtol=1e-6, atol=1e-8)


def test_improved_taa_sobel_weights_by_hand():
    # Constant colour and depth, albedo luminance a step 0 | 0.25: |Gx| = 4 * 0.25 = 1 on both
    # sides of the step, so g = 0.3 * 1 = 0.3 and sobel = sqrt(g^2 (3 - 2g)) = sqrt(0.216).
    h, w = 4, 6
    albedo = np.zeros((h, w, 3), F)
    albedo[:, 3:] = 0.25
    frame = dict(color=np.full((h, w, 3), 0.5, F), albedo=albedo, depth=np.full((h, w), 10.0, F),
                 prev_depth=np.full((h, w), 10.0, F), object_id=np.ones((h, w), np.int32),
                 motion=np.zeros((h, w, 2), F))
    tech = taa_impl.make("taa_improved")
    tech.process(frame, jitter=(0, 0), far=100.0)
    s = tech.debug_terms()["sobel_raw"]
    assert s[1, 2] == pytest.approx(np.sqrt(0.216), rel=1e-6)
    assert s[1, 3] == pytest.approx(np.sqrt(0.216), rel=1e-6)
    assert s[1, 0] == 0.0


# --------------------------------------------------- the reference's bound and the study's protocols
def test_reference_bound_and_target_defaults_everywhere():
    # spec: every pixel's display-domain SE within 0.5 LSB of 8 bits; mean noise 60 dB
    import inspect

    from references import ReferenceCache, render_reference, settings
    from study.config.profile import Profile
    from study.config.studyfile import StudyModel
    assert settings.DEFAULTS == {"se_bound_lsb": 0.5, "target_noise_db": 60.0}
    assert StudyModel(name="x").reference == {"se_bound_lsb": 0.5, "target_noise_db": 60.0}
    assert dict(Profile.__dataclass_fields__["ref_settings"].default) == {"se_bound_lsb": 0.5, "target_noise_db": 60.0}
    for fn in (render_reference, ReferenceCache.get, ReferenceCache.has):
        sig = inspect.signature(fn).parameters
        assert (sig["se_bound_lsb"].default, sig["target_noise_db"].default) == (0.5, 60.0), fn


def test_the_built_in_warm_ups_are_whole_jitter_periods():
    # the warm ghosting protocol's warm-up ends where a jitter period ends (224 = 14 x 16), so its
    # first judged frame has the same jitter phase as the cold protocol's
    from study.config.studyfile import profile
    for name in ("quick", "full"):
        warm = [g for g in profile(name).ghosting if g.warmup]
        assert warm and all(g.warmup % TAA_PERIOD == 0 for g in warm), name
    assert [g.warmup for g in profile("quick").ghosting] == [0, 224]

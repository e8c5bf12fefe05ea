"""Upscaling (taa_impl.upscale, taa_impl.taau): render sizes, FSR 2's phase count, the Lanczos-2
kernel by hand and against NumPy in float64, the spatial floor, TAAU's reduction to the baseline
TAA at scale 1, the render frustum, and the driver rendering below the output's size."""
from __future__ import annotations

import math

import numpy as np
import pytest

import backend  # noqa: F401
from backend import array, mi

import taa_impl
from raster import Rasterizer
from scenes.jitter import halton_offset
from study.config.protocols import static_schedule
from study.config.techniques import TechniqueConfig as TC
from study.engine.drive import run_schedule
from study.engine.tasks import load_scene
from taa_impl import kernels as K
from taa_impl.upscale import fsr2_phase_count, lanczos2, lanczos2_sample, render_size


def test_render_size_truncates_as_fsr2_and_refuses_bad_scales():
    assert render_size(320, 180, 0.5) == (160, 90)
    assert render_size(320, 180, 0.67) == (214, 120)     # 214.4, 120.6 truncated
    assert render_size(1600, 900, 0.77) == (1232, 693)
    assert render_size(320, 180, 1.0) == (320, 180)
    for bad in (0.0, 1.5, -0.5, math.nan, 0.05):
        with pytest.raises(ValueError, match="render_scale"):
            render_size(320, 180, bad)


def test_fsr2_phase_count_at_its_quality_ratios():
    # int(8 ratio^2): 8, 18, 23 (23.12), 32, 72 at ratios 1, 1.5, 1.7, 2, 3
    assert [fsr2_phase_count(100, o) for o in (100, 150, 170, 200, 300)] == [8, 18, 23, 32, 72]


def _lanczos_np(x):
    x = np.abs(np.asarray(x, np.float64))
    out = np.where(x < 2, np.sinc(x) * np.sinc(x / 2), 0.0)
    return out


def test_lanczos2_by_hand():
    xs = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, -0.5]
    got = np.asarray(lanczos2(mi.Float(xs)))
    # sinc(0.5) sinc(0.25) = (2/pi)(2 sqrt(2)/pi); sinc(1.5) sinc(0.75) = (-2/(3 pi))(2 sqrt(2)/(3 pi))
    want = [1.0, (2 / math.pi) * (2 * math.sqrt(2) / math.pi), 0.0,
            (-2 / (3 * math.pi)) * (2 * math.sqrt(2) / (3 * math.pi)), 0.0, 0.0,
            (2 / math.pi) * (2 * math.sqrt(2) / math.pi)]
    np.testing.assert_allclose(got, want, atol=2e-7)
    np.testing.assert_allclose(got, _lanczos_np(xs), atol=2e-7)


def _lanczos_sample_np(img, px, py):
    """float64 oracle: separable 4x4 Lanczos-2, normalised, clamp-to-edge, no dering."""
    h, w = img.shape
    out = np.empty(len(px))
    for n, (x, y) in enumerate(zip(px, py)):
        u, v = x - 0.5, y - 0.5
        x0, y0 = math.floor(u), math.floor(v)
        acc = wsum = 0.0
        for j in range(-1, 3):
            for i in range(-1, 3):
                wgt = _lanczos_np(u - (x0 + i)) * _lanczos_np(v - (y0 + j))
                acc += wgt * img[min(max(y0 + j, 0), h - 1), min(max(x0 + i, 0), w - 1)]
                wsum += wgt
        out[n] = acc / wsum
    return out


def test_lanczos2_sample_matches_a_float64_oracle_and_reproduces_texels(rng):
    h, w = 9, 13
    img = rng.random((h, w))
    grid = K.Grid(w, h)
    px, py = rng.uniform(0, w, 200), rng.uniform(0, h, 200)
    f = array(mi.Float, img.astype(np.float32))
    got = np.asarray(lanczos2_sample(grid, f, mi.Float(px.astype(np.float32)), mi.Float(py.astype(np.float32)),
                                     dering=False))
    np.testing.assert_allclose(got, _lanczos_sample_np(img, px.astype(np.float32), py.astype(np.float32)),
                               atol=2e-6)
    # at texel centres the kernel is 1 there and 0 at the other taps: the texel itself
    cx, cy = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    at = np.asarray(lanczos2_sample(grid, f, mi.Float(cx.ravel()), mi.Float(cy.ravel())))
    np.testing.assert_allclose(at, img.ravel(), atol=1e-6)
    # dering: inside the 2x2 nearest texels' range
    der = np.asarray(lanczos2_sample(grid, f, mi.Float(px.astype(np.float32)), mi.Float(py.astype(np.float32))))
    x0 = np.clip(np.floor(px - 0.5).astype(int), -1, w - 1)
    y0 = np.clip(np.floor(py - 0.5).astype(int), -1, h - 1)
    quad = np.stack([img[np.clip(y0 + j, 0, h - 1), np.clip(x0 + i, 0, w - 1)] for j in (0, 1) for i in (0, 1)])
    assert np.all(der >= quad.min(0) - 1e-6) and np.all(der <= quad.max(0) + 1e-6)


def _frame(rng, w, h, motion=0.0):
    return {"color": rng.random((h, w, 3)).astype(np.float32) * 2,
            "depth": (1 + rng.random((h, w))).astype(np.float32),
            "motion": np.full((h, w, 2), motion, np.float32)}


@pytest.mark.parametrize("filt", ["bilinear", "lanczos2"])
def test_the_spatial_floor_at_scale_1_is_no_aa_and_a_ramp_upsamples_exactly(rng, filt):
    tech = taa_impl.make("upscale_spatial", render_scale=1.0, filter=filt)
    fr = _frame(rng, 12, 8)
    out = tech.process(fr, jitter=(0, 0), far=10.0, output_size=(12, 8))
    np.testing.assert_allclose(out, fr["color"], atol=1e-6)
    # a ramp along x at 0.5: bilinear reproduces it exactly away from the clamped border
    ramp = np.broadcast_to(np.arange(8, dtype=np.float32)[None, :, None], (5, 8, 3)).copy()
    bil = taa_impl.make("upscale_bilinear", render_scale=0.5)
    out = bil.process({"color": ramp}, jitter=(0, 0), far=10.0, output_size=(16, 10))
    xs = (np.arange(16) + 0.5) * 0.5 - 0.5
    np.testing.assert_allclose(out[3, 2:-2, 0], xs[2:-2], atol=1e-6)
    with pytest.raises(ValueError, match="renders 8x5, got a 12x8 frame"):
        bil.process(fr, jitter=(0, 0), far=10.0, output_size=(16, 10))
    with pytest.raises(ValueError, match="output_size"):
        bil.process({"color": ramp}, jitter=(0, 0), far=10.0)


def test_taau_with_the_box_filter_at_scale_1_is_the_baseline_taa_unsharpened(rng):
    taau = taa_impl.make("taau", render_scale=1.0)
    base = taa_impl.make("taa_baseline", sharpen="none")
    for k in range(12):
        fr = _frame(rng, 20, 14, motion=0.3 * (k % 3))
        j = halton_offset(k)
        a = taau.process(fr, jitter=j, far=10.0, output_size=(20, 14), reset=k == 0)
        b = base.process(fr, jitter=j, far=10.0, reset=k == 0)
        np.testing.assert_array_equal(a, b)


def test_taau_at_half_scale_takes_a_sample_only_where_it_lands():
    """A grey history, then a checkerboard frame whose jitter puts each sample on the centre of the
    output pixel up-left of its render pixel's: those output pixels move halfway to it, the others
    keep the history (the checkerboard's box holds the grey: no clip)."""
    taau = taa_impl.make("taau", render_scale=0.5, k_min=0.5, k_max=0.5)
    w, h = 8, 6
    rh, rw = h // 2, w // 2
    base = {"depth": np.ones((rh, rw), np.float32), "motion": np.zeros((rh, rw, 2), np.float32)}
    taau.process(dict(base, color=np.full((rh, rw, 3), 0.5, np.float32)), jitter=(0, 0), far=10.0,
                 output_size=(w, h), reset=True)
    checker = (np.indices((rh, rw)).sum(0) % 2).astype(np.float32)
    out = taau.process(dict(base, color=np.repeat(checker[..., None], 3, -1)), jitter=(-0.25, -0.25),
                       far=10.0, output_size=(w, h))
    # samples at render x + 0.25 = output 2x + 0.5: the centre of output pixel 2x (and row 2y)
    want = np.full((h, w), 0.5, np.float32)
    want[0::2, 0::2] = 0.5 * checker + 0.25      # lerp(c, 0.5, k = 0.5)
    np.testing.assert_allclose(out[..., 0], want, atol=1e-6)
    conf = taau.debug_terms()["confidence"]
    assert np.all(conf[0::2, 0::2] == 1) and np.all(conf[1::2, :] == 0) and np.all(conf[:, 1::2] == 0)


def test_a_render_below_the_output_size_keeps_the_output_frustum():
    """Render pixel (x, y) at scale 0.5 sees what output pixel (2x, 2y) sees with jitter (+0.5, +0.5)."""
    scene = load_scene("pipe")
    small = Rasterizer(scene, 40, 23, aspect=80 / 46)
    full = Rasterizer(scene, 80, 46)
    try:
        a = small.render(0, (0.0, 0.0), ("depth", "object_id"))
        b = full.render(0, (0.5, 0.5), ("depth", "object_id"))
    finally:
        small.close()
        full.close()
    same = a["object_id"] == b["object_id"][0::2, 0::2]
    assert same.mean() > 0.99
    np.testing.assert_allclose(a["depth"][same], b["depth"][0::2, 0::2][same], rtol=1e-4)


def test_the_driver_renders_an_upscaler_below_the_output_and_jitters_with_its_period():
    scene = load_scene("pipe")
    cfgs = [TC("TAAU", "taau", (("render_scale", 0.5),)), TC("No AA", "noaa")]
    out = run_schedule(scene, 32, 18, static_schedule(0, 4, [1, 4]), cfgs, {}, progress=False)
    assert {f: im.shape for f, im in out["TAAU"]["images"].items()} == {1: (18, 32, 3), 4: (18, 32, 3)}
    assert out["No AA"]["images"][4].shape == (18, 32, 3)
    tech = taa_impl.make("taau", render_scale=0.5)
    assert tech.inputs.render_scale == 0.5 and tech.inputs.upsamples
    assert tech.inputs.shaded_samples() == pytest.approx(0.25)

"""The FSR 2-class upscaler (taa_impl.fsr2, taa_impl.fsr2_passes): each pass against hand-computed
cases, the accumulate pass against a NumPy float64 oracle over a few frames, and a rendered static
scene converging (with TAAU beside it) above the spatial floor."""
from __future__ import annotations

import math

import numpy as np
import pytest

import backend  # noqa: F401
from backend import array, dr, mi

import taa_impl
from scenes.camera import CameraState, look_at
from scenes.jitter import halton_offset
from study.config.protocols import static_schedule
from study.config.techniques import TechniqueConfig as TC
from study.engine.drive import run_schedule
from study.engine.tasks import load_scene
from taa_impl import fsr2_passes as P
from taa_impl import kernels as K
from taa_impl.upscale import Frames


def _img(a):
    a = np.asarray(a, np.float32)
    return dr.unravel(mi.Color3f, array(mi.Float, a)) if a.ndim == 3 else array(mi.Float, a)


def _np(x, h, w):
    return np.asarray(dr.ravel(x) if isinstance(x, mi.Color3f) else x, np.float64).reshape(
        (h, w, 3) if isinstance(x, mi.Color3f) else (h, w))


def test_rcas_on_a_step_edge_by_hand():
    """0.2 | 0.8: hitMin = 0.2 / 3.2, hitMax = 0.2 / (0.8 - 4): lobe -1/16 on both sides of the edge,
    out = (lobe sum(n) + e) / (4 lobe + 1): 0.15 left, 0.85 right; flat pixels stay as they are."""
    img = np.full((4, 6, 3), 0.2, np.float32)
    img[:, 3:] = 0.8
    g = K.Grid(6, 4)
    out = _np(P.rcas(g, _img(img), 0.0), 4, 6)[..., 0]
    np.testing.assert_allclose(out[1], [0.2, 0.2, 0.15, 0.85, 0.8, 0.8], atol=1e-6)
    # 1 stop halves the lobe: (-1/32 * 1.4 + 0.2) / (1 - 1/8)
    half = _np(P.rcas(g, _img(img), 1.0), 4, 6)[1, 2, 0]
    assert half == pytest.approx((-1 / 32 * 1.4 + 0.2) / (1 - 1 / 8), abs=1e-6)


def test_reversible_tonemap_round_trips():
    c = _img(np.random.default_rng(1).random((5, 7, 3)) * 50)
    np.testing.assert_allclose(_np(P.inverse_tonemap(P.tonemap(c)), 5, 7), _np(c, 5, 7), rtol=2e-5)
    t = _np(P.tonemap(c), 5, 7)
    assert t.max() < 1 and t.min() >= 0


def test_thin_features_lock_and_blocks_do_not():
    lum = np.full((9, 12), 0.2, np.float32)
    lum[2, 2] = 1.0                       # a single bright pixel: a ridge, in no similar 2x2
    lum[5:7, 5:7] = 1.0                   # a 2x2 block: every pixel of it is in a similar quad
    lum[:, 10] = 0.05                     # a one-pixel dark line
    fr = Frames.of(12, 9, 12, 9)
    thin = _np(mi.Float(P.thin_feature(fr, _img(lum))), 9, 12) > 0.5
    assert thin[2, 2] and not thin[5:7, 5:7].any()
    assert thin[1:-1, 10].all()
    flat = np.ones((9, 12), bool)
    flat[1:4, 1:4] = flat[4:8, 4:8] = False
    flat[:, 9:12] = False
    assert not thin[flat].any()
    # a lock lands at the output pixel the jittered sample lies in (scale 0.5, jitter +0.25: 2x + 1)
    fr2 = Frames.of(12, 9, 24, 18)
    locks = _np(mi.Float(P.create_locks(fr2, P.thin_feature(fr2, _img(lum)), (0.25, 0.25))), 18, 24) > 0.5
    assert locks[5, 5] and locks.sum() == thin.sum()


def test_reconstructed_previous_depth_and_the_depth_clip_by_hand():
    w, h, far = 8, 6, 100.0
    fr = Frames.of(w, h, w, h)
    depth = np.full((h, w), 10.0, np.float32)
    motion = np.zeros((h, w, 2), np.float32)
    motion[..., 0] = 2.0                    # everything moved 2 pixels right
    _, _, prev = P.reconstruct_and_dilate(fr, _img(depth), dr.unravel(mi.Vector2f, array(mi.Float, motion)), far)
    prev = _np(prev, h, w)
    # pixel x came from x - 1.5: texels x - 2 and x - 1; the last column is written by nobody
    np.testing.assert_array_equal(prev[:, :w - 1], 10.0)
    np.testing.assert_array_equal(prev[:, w - 1], far)
    # depth clip: previous depth 5 on the left (something nearer was there), 10 on the right
    tan_half = (0.6, 0.4)
    kfov = math.sqrt(0.36 + 0.16 + 1)
    sep = P.KSEP * kfov * math.hypot(w, h) * 10.0
    prev_depth = np.full((h, w), 10.0, np.float32)
    prev_depth[:, :3] = 10.0 - 2 * sep          # a separation of twice the required one
    prev_depth[:, 3:5] = 5.0
    zero = dr.zeros(mi.Vector2f, w * h)
    clip = _np(P.depth_clip(fr, _img(depth), zero, _img(prev_depth), tan_half), h, w)
    power = 1 + 2 * math.hypot(w, h) / math.hypot(1920, 1080)
    np.testing.assert_allclose(clip[:, :3], 1 - 0.5 ** power, atol=1e-4)
    np.testing.assert_allclose(clip[:, 3:5], 1.0, atol=1e-3)
    np.testing.assert_array_equal(clip[:, 5:], 0.0)


# -- the accumulate pass against NumPy float64 -----------------------------------------------------
def _lz(x):
    x = np.abs(x)
    return np.where(x < 2, np.sinc(x) * np.sinc(x / 2), 0.0)


def _ycocg(c):
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    return np.stack([0.25 * r + 0.5 * g + 0.25 * b, 0.5 * r - 0.5 * b, 0.5 * g - 0.25 * r - 0.25 * b], -1)


def _rgb(y):
    Y, co, cg = y[..., 0], y[..., 1], y[..., 2]
    return np.stack([Y + co - cg, Y + cg, Y - co - cg], -1)


def _tm(c):
    return c / (c.max(-1, keepdims=True) + 1)


def _itm(c):
    return c / np.maximum(1 - c.max(-1, keepdims=True), 1e-6)


def _oracle_step(state, c, jit, w, h, max_acc=32.0, fixed=False):
    """One static frame (no motion, locks, depth clip, instability, exposure or RCAS), float64."""
    rh, rw = c.shape[:2]
    sx, sy = rw / w, rh / h
    fresh = state is None
    bias_max = min(1.99, 1 / sx)
    bias = max(1.0, (1 + bias_max) * 0.3) if fresh else bias_max
    cur = _ycocg(c.astype(np.float64))
    out = np.zeros((h, w, 3))
    weight_out = np.zeros((h, w))
    influence = min(20.0, (1 / (sx * sy)) ** 3)
    for Y in range(h):
        for X in range(w):
            ux, uy = (X + 0.5) * sx, (Y + 0.5) * sy
            ix, iy = math.floor(ux), math.floor(uy)     # FSR 2's 3x3 around floor(output centre)
            acc, ws, m1, m2, bw = np.zeros(3), 0.0, np.zeros(3), np.zeros(3), 0.0
            amin, amax = np.full(3, np.inf), np.full(3, -np.inf)
            for yi in (iy - 1, iy, iy + 1):
                for xi in (ix - 1, ix, ix + 1):
                    if not (0 <= xi < rw and 0 <= yi < rh):
                        continue
                    s = cur[yi, xi]
                    ox, oy = xi + 0.5 + jit[0] - ux, yi + 0.5 + jit[1] - uy
                    wt = float(_lz(math.hypot(ox, oy) * bias))
                    acc, ws = acc + s * wt, ws + wt
                    b = math.exp(-2.0 * (ox * ox + oy * oy))
                    m1, m2, bw = m1 + s * b, m2 + s * s * b, bw + b
                    amin, amax = np.minimum(amin, s), np.maximum(amax, s)
            ok = ws > 1e-3
            col = np.clip(acc / ws, amin, amax) if ok else acc
            centre = m1 / bw
            vec = np.sqrt(np.abs(m2 / bw - centre ** 2))
            w_up = (ws if ok else 0.0) / (12.0 if fixed else 1.0)
            up = np.maximum(_rgb(col), 0)
            if fresh:
                hist, wgt = up, 0.0
            else:
                hist, wgt = np.maximum(state[0][Y, X], 0), (1.0 if fixed else min(state[1][Y, X], max_acc))
                hy = _ycocg(hist)
                bmin, bmax = np.maximum(amin, centre - vec * influence), np.minimum(amax, centre + vec * influence)
                tol = 2 / 255
                if np.any(hy < bmin - tol) or np.any(hy > bmax + tol):
                    hist, wgt = np.maximum(_rgb(np.clip(hy, bmin, bmax)), 0), min(wgt, 0.1)
            total = max(wgt + w_up, 1e-6)
            alpha = 1.0 if fresh else w_up / total
            out[Y, X] = _itm(_tm(hist) + (_tm(up) - _tm(hist)) * alpha)
            weight_out[Y, X] = min(total, 2 * max_acc)
    return (out, weight_out), np.maximum(out, 0)


@pytest.mark.parametrize("scale, history", [(1.0, "accumulated"), (0.5, "accumulated"), (0.5, "fixed")])
def test_the_accumulate_pass_matches_a_float64_oracle(rng, scale, history):
    w, h = 12, 8
    rw, rh = int(w * scale), int(h * scale)
    tech = taa_impl.make("fsr2", render_scale=scale, enable_sharpening=False, locks=False, depth_clip=False,
                         luma_instability=False, auto_exposure=False, history=history)
    cam = CameraState(look_at((0, 0, 5), (0, 0, 0), (0, 1, 0)), 45.0, 0.1, 100.0, w, h)
    state = None
    base = rng.random((rh, rw, 3)) * 1.5
    for k in range(6):
        c = (base + 0.05 * rng.standard_normal((rh, rw, 3))).clip(0).astype(np.float32)
        frame = {"color": c, "depth": np.full((rh, rw), 3.0, np.float32), "motion": np.zeros((rh, rw, 2), np.float32)}
        jit = halton_offset(k, tech.inputs.jitter_period)
        got = tech.process(frame, jitter=jit, far=100.0, output_size=(w, h), reset=k == 0, cameras=(cam, cam))
        state, want = _oracle_step(state, c, jit, w, h, fixed=history == "fixed")
        np.testing.assert_allclose(got, want, atol=2e-4, rtol=2e-4)


def test_fsr2_and_taau_converge_on_a_static_scene_above_the_spatial_floor():
    scene = load_scene("pipe")
    w, h = 96, 54
    cfgs = [TC("FSR 2", "fsr2", (("render_scale", 0.5),)), TC("TAAU", "taau", (("render_scale", 0.5),)),
            TC("Lanczos", "upscale_spatial", (("render_scale", 0.5),))]
    out = run_schedule(scene, w, h, static_schedule(0, 48, [1, 8, 48]), cfgs, {}, progress=False)
    gt = next(iter(run_schedule(scene, w, h, static_schedule(0, 1, [1]), [TC("acc", "accumulation", (("samples", 64),))],
                                {}, progress=False)["acc"]["images"].values()))

    def psnr(img):
        enc = [np.round(np.clip(np.maximum(x, 0) / (1 + np.maximum(x, 0)), 0, 1) ** (1 / 2.2) * 255) for x in (img, gt)]
        return 10 * math.log10(255 ** 2 / np.mean((enc[0] - enc[1]) ** 2))
    floor = psnr(out["Lanczos"]["images"][48])
    for label in ("FSR 2", "TAAU"):
        p = {f: psnr(im) for f, im in out[label]["images"].items()}
        assert p[1] < p[8] < p[48], (label, p)
        assert p[48] > floor + 1.0, (label, p, floor)

"""FSR 2's RCAS and upsample passes (taa_impl.fsr2_passes) against a float64 NumPy transcription
of AMD's published shaders (tests/oracle_fsr2.py), on small images: equal to float32 rounding
where the study follows FSR 2, and apart only where taa_impl.fsr2 says it departs."""
from __future__ import annotations

import math

import numpy as np
import pytest

import backend  # noqa: F401
from backend import array, dr, mi

import oracle_fsr2 as O
from test_fsr2 import _img, _np
from taa_impl import fsr2_passes as P
from taa_impl import kernels as K
from taa_impl.upscale import Frames


def _rcas_image(seed, h=12, w=16):
    """Tone-mapped colours in [0, 1): a near-flat patch (where the lobe limit binds), an edge,
    bright and dark single pixels, and noise."""
    rng = np.random.default_rng(seed)
    img = rng.random((h, w, 3)) * 0.98
    img[:6, :8] = 0.45 + 0.04 * rng.random((6, 8, 3))       # flat: ring min/max within 10 %
    img[6:, 8:] = np.where(np.arange(8)[None, :, None] < 4, 0.1, 0.9)
    img[2, 12], img[9, 3] = 0.97, 0.01
    return img


@pytest.mark.parametrize("stops", [0.0, 0.4, 1.0])
@pytest.mark.parametrize("seed", [1, 2])
def test_rcas_matches_the_fsr2_oracle(stops, seed):
    img = _rcas_image(seed)
    h, w = img.shape[:2]
    got = _np(P.rcas(K.Grid(w, h), _img(img), stops), h, w)
    want = O.rcas(img.astype(np.float32), stops)
    np.testing.assert_allclose(got, want, atol=1e-5 * np.abs(want).max(), rtol=0)
    # the output stays in [0, 1] (what RCAS solves its lobe for), and sharpens: it differs from
    # the input at many pixels
    assert got.min() >= -1e-6 and got.max() <= 1 + 1e-6
    assert np.count_nonzero(np.abs(got - img) > 1e-3) > 50


def test_rcas_limit_binds_on_the_flat_patch():
    """On the near-flat patch every lobe is at the limit: the output is
    (-L (b + d + f + h) + e) / (1 - 4 L) with L = 1/4 - 1/16, computed here by hand for one pixel."""
    img = _rcas_image(1)
    y, x = 3, 4
    e = img[y, x].astype(np.float32).astype(np.float64)
    ring = sum(img[y + dy, x + dx].astype(np.float32).astype(np.float64) for dx, dy in ((0, -1), (-1, 0), (1, 0), (0, 1)))
    lim = 0.25 - 1.0 / 16.0
    hand = (-lim * ring + e) / (1.0 - 4.0 * lim)
    got = _np(P.rcas(K.Grid(16, 12), _img(img), 0.0), 12, 16)[y, x]
    np.testing.assert_allclose(got, hand, atol=1e-6)
    np.testing.assert_allclose(O.rcas(img.astype(np.float32), 0.0)[y, x], hand, atol=1e-12)


def test_rcas_fsr2_and_fsr1_limiters_differ_only_at_a_local_extremum():
    """FSR 2's FsrRcasF limits with the ring's min/max; FSR 1.0's (the study's) with the centre
    taken in. Where the centre lies within its ring the two are the same; at a peak FSR 2's
    overshoots [0, 1] (here 0.99 on 0.5: lobe -3/16, (0.99 - 0.375) / 0.25 = 2.46), which on the
    tone-mapped output the inverse tone map could not undo."""
    img = _rcas_image(2)
    a = O.rcas(img, 0.0, centre_in_limiters=True)
    b = O.rcas(img, 0.0, centre_in_limiters=False)
    ring = np.stack([O._tap(img, dx, dy) for dx, dy in ((0, -1), (-1, 0), (1, 0), (0, 1))])
    inside = np.all((img >= ring.min(0)) & (img <= ring.max(0)), axis=-1)
    assert inside.sum() > 50
    np.testing.assert_allclose(a[inside], b[inside], atol=1e-12)
    peak = np.full((3, 3, 3), 0.5)
    peak[1, 1] = 0.99
    assert O.rcas(peak, 0.0, centre_in_limiters=False)[1, 1, 0] == pytest.approx((0.99 - 0.375) / 0.25)
    # with the centre taken in, the lobe is solved for exactly 1: (1 - 0.99) / (4 * 0.5 - 4)
    assert O.rcas(peak, 0.0)[1, 1, 0] == pytest.approx(1.0, abs=1e-12)


def _close(got, want, mask=Ellipsis):
    """Each output within 1e-5 of its peak. The box's std is the root of a difference of float32
    moments (ill-conditioned where the variance is small): its square, the variance, is compared."""
    for k in want:
        g, w = (got[k] ** 2, want[k] ** 2) if k == "vec" else (got[k], want[k])
        peak = max(np.abs(w).max(), 1e-3)
        np.testing.assert_allclose(g[mask], w[mask], atol=1e-5 * peak, rtol=0, err_msg=k)


def _upsample(img, w, h, jitter, kb, cb):
    rh, rw = img.shape[:2]
    fr = Frames.of(rw, rh, w, h)
    col, wsum, centre, vec, amin, amax = P.upsample(fr, _img(img), jitter, array(mi.Float, kb.ravel(), np.float32),
                                                    array(mi.Float, cb.ravel(), np.float32))
    return {"colour": _np(col, h, w), "weight": _np(wsum, h, w), "centre": _np(centre, h, w),
            "vec": _np(vec, h, w), "aabb_min": _np(amin, h, w), "aabb_max": _np(amax, h, w)}


CASES = [
    ((12, 8), (12, 8), (0.0, 0.0)),         # 1, samples on the output centres
    ((12, 8), (12, 8), (0.31, -0.22)),
    ((8, 6), (12, 9), (-0.4, 0.13)),        # 0.67
    ((8, 6), (12, 9), (0.0, 0.0)),          # 0.67, a third of the centres on integers: floor(u) at a tie
    ((10, 7), (13, 9), (0.27, 0.41)),       # 0.77
    ((6, 4), (12, 8), (0.45, 0.45)),        # 0.5, weight sums <= FSR2_EPSILON at 16 of 96
    ((6, 4), (12, 8), (0.0, 0.0)),          # 0.5, centres a quarter sample off the nearest
]


def _case(render, output, seed=3):
    rng = np.random.default_rng(seed)
    (rw, rh), (w, h) = render, output
    img = (rng.random((rh, rw, 3)) * np.array([1.0, 0.5, 0.5]) - np.array([0.0, 0.25, 0.25])).astype(np.float32)
    bias_max = min(1.99, w / rw)
    kb = rng.uniform(max(1.0, (1 + bias_max) * 0.3), bias_max + 1e-9, (h, w))   # FSR 2's kernel bias range
    cb = rng.uniform(-3.0, -2.0, (h, w))                                          # its rectification curve
    return img, kb.astype(np.float32), cb.astype(np.float32)


def _interior(render, output):
    """Output pixels whose nine samples (floor(centre) + {-1, 0, 1}^2) are all on-screen."""
    (rw, rh), (w, h) = render, output
    ix = np.floor(np.float32(np.arange(w) + 0.5) * np.float32(rw / w))
    iy = np.floor(np.float32(np.arange(h) + 0.5) * np.float32(rh / h))
    return ((iy >= 1) & (iy <= rh - 2))[:, None] & ((ix >= 1) & (ix <= rw - 2))[None, :]


@pytest.mark.parametrize("render, output, jitter", CASES)
def test_upsample_matches_the_oracle(render, output, jitter):
    """Everywhere, against FSR 2's form with the study's one departure (off-screen samples out of
    the rectification box)."""
    (w, h) = output
    img, kb, cb = _case(render, output)
    got = _upsample(img, w, h, jitter, kb, cb)
    _close(got, O.upsample(img, w, h, jitter, kb, cb, offscreen="skip"))


@pytest.mark.parametrize("render, output, jitter", CASES)
def test_the_study_upsample_is_fsr2s(render, output, jitter):
    """FSR 2.2.1's upsample itself (off-screen samples read as 0): every output the same where the
    nine samples are on-screen, and the weights everywhere (off-screen samples weigh nothing in
    both); at the border only the box, which FSR 2 darkens with its out-of-range loads, differs."""
    (w, h) = output
    img, kb, cb = _case(render, output)
    got = _upsample(img, w, h, jitter, kb, cb)
    want = O.upsample(img, w, h, jitter, kb, cb)
    inner = _interior(render, output)
    assert inner.sum() >= 8
    _close(got, want, inner)
    np.testing.assert_allclose(got["weight"], want["weight"], atol=1e-5 * np.abs(want["weight"]).max(), rtol=0)
    assert not np.allclose(got["aabb_min"][~inner], want["aabb_min"][~inner])


def test_upsample_weight_at_scale_1_is_symmetric():
    """At scale 1 without jitter every sample lies on an output centre: an interior pixel's weight
    is 1 + 4 Lanczos-2(sqrt 2) (the sides at Lanczos-2(1) = 0), its colour the Lanczos mean of
    the 3x3, deringed into its min/max."""
    img, _, _ = _case((12, 8), (12, 8))
    got = _upsample(img, 12, 8, (0.0, 0.0), np.ones((8, 12)), np.full((8, 12), -2.0))
    l2 = O.lanczos2(math.sqrt(2.0))
    np.testing.assert_allclose(got["weight"][1:-1, 1:-1], 1.0 + 4.0 * l2, atol=1e-6)
    y, x = 3, 5
    blk = img[y - 1:y + 2, x - 1:x + 2].astype(np.float64)
    corners = blk[0, 0] + blk[0, 2] + blk[2, 0] + blk[2, 2]
    hand = np.clip((blk[1, 1] + l2 * corners) / (1.0 + 4.0 * l2), blk.min((0, 1)), blk.max((0, 1)))
    np.testing.assert_allclose(got["colour"][y, x], hand, atol=1e-6)


def test_fsr2_upsample_oracle_by_hand():
    """FSR 2.2.1's upsample (the oracle's default) at scale 1 without jitter: the 3x3 around
    each pixel, weights 1 at the centre, Lanczos-2(1) = 0 on the sides, Lanczos-2(sqrt 2) at the
    corners, off-screen samples weighing nothing; a constant image comes back unchanged. Its box
    reads off-screen samples as 0: at a corner pixel five of the nine, so the box centre is
    0.3 (1 + 2 e^-2 + e^-4) / (1 + 4 e^-2 + 4 e^-4) and the aabb reaches 0."""
    l2 = O.lanczos2(math.sqrt(2.0))
    assert l2 == pytest.approx(2 * math.sin(math.pi * math.sqrt(2)) * math.sin(math.pi * math.sqrt(0.5))
                               / (2 * math.pi ** 2), rel=1e-12)
    assert O.lanczos2(1.0) == pytest.approx(0.0, abs=1e-15) and O.lanczos2(2.5) == pytest.approx(0.0, abs=1e-15)
    flat = np.full((5, 6, 3), 0.3)
    r = O.upsample(flat, 6, 5, (0.0, 0.0), 1.0, -2.0)
    np.testing.assert_allclose(r["colour"], 0.3, atol=1e-12)
    np.testing.assert_allclose(r["vec"][1:-1, 1:-1], 0.0, atol=1e-7)
    assert r["weight"][2, 2] == pytest.approx(1.0 + 4.0 * l2, abs=1e-12)
    assert r["weight"][0, 0] == pytest.approx(1.0 + l2, abs=1e-12)
    e2, e4 = math.exp(-2), math.exp(-4)
    assert r["centre"][0, 0, 0] == pytest.approx(0.3 * (1 + 2 * e2 + e4) / (1 + 4 * e2 + 4 * e4), rel=1e-12)
    assert r["aabb_min"][0, 0, 0] == 0.0 and r["aabb_max"][0, 0, 0] == 0.3
    s = O.upsample(flat, 6, 5, (0.0, 0.0), 1.0, -2.0, offscreen="skip")
    np.testing.assert_allclose(s["centre"], 0.3, atol=1e-12)
    np.testing.assert_allclose(s["aabb_min"], 0.3, atol=1e-12)
    # a box weight exp(-2 |offset|^2): centre 1, sides e^-2, corners e^-4
    img = np.zeros((3, 3, 3))
    img[1, 1] = 1.0
    r = O.upsample(img, 3, 3, (0.0, 0.0), 1.0, -2.0)
    assert r["centre"][1, 1, 0] == pytest.approx(1.0 / (1 + 4 * math.exp(-2) + 4 * math.exp(-4)), rel=1e-12)

import math

import numpy as np
import pytest

from study.metrics import judging, temporal
from study.metrics import suite as metrics


def test_mse_psnr_snr_by_hand():
    ref = np.full((4, 4, 3), 100, np.uint8)
    x = ref.copy()
    x[0, 0, 0] = 110                                    # one error of 10 over 48 values
    m = metrics.mse(ref, x)
    assert m == pytest.approx(100 / 48)
    assert metrics.psnr_from_mse(m) == pytest.approx(10 * math.log10(255 ** 2 * 48 / 100))
    assert metrics.snr(ref, x) == pytest.approx(10 * math.log10(48 * 100 ** 2 / 100))
    assert metrics.psnr_from_mse(0.0) == math.inf and metrics.snr(ref, ref) == math.inf


def test_ssim_identical_is_one_and_map_is_white():
    rng = np.random.default_rng(3)
    a = rng.integers(0, 256, (32, 32, 3), dtype=np.uint8)
    s, smap = metrics.ssim(a, a)
    assert s == pytest.approx(1.0) and np.allclose(smap, 1.0)
    b = np.clip(a.astype(int) + rng.integers(-40, 40, a.shape), 0, 255).astype(np.uint8)
    s2, smap2 = metrics.ssim(a, b)
    assert 0 < s2 < 0.99 and smap2.shape == (32, 32)


def test_all_metrics_and_nan_refused():
    rng = np.random.default_rng(4)
    lin = rng.random((16, 16, 3)).astype(np.float32)
    disp = lin ** (1 / 2.2)
    d8 = np.round(disp * 255).astype(np.uint8)
    out, maps = judging.all_metrics(lin, disp, d8, lin, disp, d8)
    assert out["mse"] == 0 and out["psnr"] == math.inf and out["ssim"] == pytest.approx(1.0)
    assert out["flip_ldr"] == pytest.approx(0.0, abs=1e-6) and out["relmse_hdr"] == 0
    bad = lin.copy()
    bad[3, 3, 1] = np.nan
    with pytest.raises(ValueError, match="1 NaN"):
        judging.all_metrics(lin, disp, d8, bad, disp, d8)


def test_temporal_instability_zero_for_a_sequence_that_follows_the_reference():
    seq = [np.full((4, 4, 3), v, np.uint8) for v in (10, 20, 30)]
    assert temporal.temporal_instability(seq, seq) == 0
    shifted = [s + 5 for s in seq]                      # constant bias: no flicker
    assert temporal.temporal_instability(seq, shifted) == 0
    flicker = [seq[0], seq[1] + 6, seq[2]]
    # frame 1 is 6 too bright: both of its differences are off by 6 in every value
    assert temporal.temporal_instability(seq, flicker) == pytest.approx(6.0)


def test_temporal_instability_is_exact_at_the_extremes_and_agrees_with_float64():
    black = [np.zeros((3, 5, 3), np.uint8)] * 3
    strobe = [np.full((3, 5, 3), v, np.uint8) for v in (0, 255, 0)]
    assert temporal.temporal_instability(black, strobe) == 255.0   # |d| = 255 at every value, twice
    rng = np.random.default_rng(7)
    ref = [rng.integers(0, 256, (9, 11, 3), dtype=np.uint8) for _ in range(5)]
    x = [rng.integers(0, 256, (9, 11, 3), dtype=np.uint8) for _ in range(5)]
    r64, x64 = [a.astype(np.float64) for a in ref], [a.astype(np.float64) for a in x]
    sq = [np.sum(((x64[i] - x64[i - 1]) - (r64[i] - r64[i - 1])) ** 2) for i in range(1, 5)]
    assert temporal.temporal_instability(ref, x) == np.sqrt(np.sum(sq) / (4 * ref[0].size))
    with pytest.raises(ValueError, match="8-bit"):
        temporal.temporal_instability([a.astype(np.float32) for a in ref], x)

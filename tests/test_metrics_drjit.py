"""The Dr.Jit SSIM and FLIP against their oracles (scikit-image 0.26.0, flip-evaluator 1.7), and
MATLAB's volume SSIM against a NumPy float64 evaluation of its definition written here."""
import math

import numpy as np
import pytest
from skimage.metrics import structural_similarity

from display import DisplayTransform
from study.metrics import flip as F
from study.metrics import flip_colour as FC
from study.metrics import judging
from study.metrics import suite as metrics

TOL = 1e-5   # the bound held on means and maps; measured margins are in the assertions' comments


def _pairs8():
    rng = np.random.default_rng(11)
    a = rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
    b = np.clip(a.astype(int) + rng.integers(-40, 41, a.shape), 0, 255).astype(np.uint8)
    yy, xx = np.mgrid[0:48, 0:64]
    s = np.stack([xx * 4, yy * 5, ((xx // 8 + yy // 8) % 2) * 255], -1).clip(0, 255).astype(np.uint8)
    t = np.roll(s, 1, axis=1)                       # a one-pixel shift: edges move, flats do not
    odd = a[:20, :37].copy()                        # width not a multiple of 8, 20 rows
    return [("random", a, b), ("structured", s, t), ("odd size", odd, b[:20, :37].copy())]


@pytest.mark.parametrize("name,a,b", _pairs8(), ids=lambda v: v if isinstance(v, str) else "")
def test_ssim_matches_scikit_image(name, a, b):
    mean, smap = metrics.ssim(a, b)
    ref_mean, ref_map = structural_similarity(a, b, gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
                                              data_range=255, channel_axis=-1, K1=0.01, K2=0.03, full=True)
    # float64 both: measured <= 5e-15 on the map
    assert abs(mean - ref_mean) < 1e-9
    assert np.abs(smap - ref_map.mean(axis=-1)).max() < 1e-9
    assert mean < 0.999                              # not a trivial pair


def _flip_pairs():
    rng = np.random.default_rng(5)
    a = rng.random((48, 64, 3)).astype(np.float32)
    b = np.clip(a + 0.08 * rng.standard_normal(a.shape).astype(np.float32), 0, 1)
    yy, xx = np.mgrid[0:48, 0:64].astype(np.float32)
    s = np.stack([xx / 63, yy / 47, ((xx // 6 + yy // 6) % 2)], -1).astype(np.float32)
    t = np.roll(s, 1, axis=0)
    small = a[:13, :21].copy()                      # smaller than the 21-tap CSF filter
    return [("random", a, b), ("structured", s, t), ("small", small, b[:13, :21].copy())]


def _flip_oracle(ref, x, mode):
    import flip_evaluator
    emap, mean, params = flip_evaluator.evaluate(np.ascontiguousarray(ref, np.float32),
                                                 np.ascontiguousarray(x, np.float32), mode, applyMagma=False)
    return mean, np.asarray(emap).reshape(ref.shape[:2]), params


@pytest.mark.parametrize("name,a,b", _flip_pairs(), ids=lambda v: v if isinstance(v, str) else "")
def test_flip_ldr_matches_flip_evaluator(name, a, b):
    mean, emap = metrics.flip(a, b, "LDR")
    ref_mean, ref_map, _ = _flip_oracle(a, b, "LDR")
    # measured on these: mean <= 4e-7, map <= 4e-6 (float32 HyAB of near-equal colours cancels)
    assert abs(mean - ref_mean) < TOL
    assert np.abs(emap - ref_map).max() < TOL
    assert emap.shape == a.shape[:2] and mean > 0.01


@pytest.mark.parametrize("name,a,b", _flip_pairs()[:2], ids=lambda v: v if isinstance(v, str) else "")
def test_flip_hdr_matches_flip_evaluator(name, a, b):
    A, B = (a ** 2.2) * 6.0, (b ** 2.2) * 6.0      # linear, up to 6: several exposures
    mean, emap = metrics.flip(A, B, "HDR")
    ref_mean, ref_map, params = _flip_oracle(A, B, "HDR")
    start, stop, n = F.exposures(A)
    assert (start, stop, n) == (np.float32(params["startExposure"]), np.float32(params["stopExposure"]),
                                params["numExposures"])
    assert abs(mean - ref_mean) < TOL
    assert np.abs(emap - ref_map).max() < TOL


def test_flip_exposures_floor_the_median_at_flt_epsilon():
    # flip-evaluator 1.7 keeps the median luminance >= FLT_EPSILON (more than half black here)
    rng = np.random.default_rng(2)
    a = (rng.random((24, 32, 3)) * 3).astype(np.float32)
    a[:16] = 0
    _, _, params = _flip_oracle(a, a * 1.1, "HDR")
    start, stop, n = F.exposures(a)
    assert stop == np.float32(params["stopExposure"]) and n == params["numExposures"] == 25
    with pytest.raises(ValueError, match="black"):
        F.exposures(np.zeros((8, 8, 3), np.float32))


def test_flip_constants_match_the_library():
    _, _, params = _flip_oracle(np.zeros((4, 4, 3), np.float32), np.zeros((4, 4, 3), np.float32), "LDR")
    assert FC.default_ppd() == np.float32(params["ppd"])
    assert FC.spatial_radius(FC.default_ppd()) == 10 and len(F.consts().feature[0]) == 19
    g, dg, ddg = F.consts().feature
    assert math.isclose(sum(g), 1, rel_tol=1e-6) and math.isclose(sum(v for v in dg if v > 0), 1, rel_tol=1e-6)


# -- MATLAB's volume SSIM -------------------------------------------------------------------------

def _volume_ssim_by_definition(a, b):
    """MATLAB ssim on an H x W x 3 array, written from its definition: 3-D Gaussian sigma 1.5,
    11 x 11 x 11 window (2*ceil(3*1.5)+1), 'replicate' padding on all three axes, population
    statistics, C1 = (0.01*255)^2, C2 = (0.03*255)^2, mean over every voxel."""
    r = 5
    t = np.arange(-r, r + 1, dtype=np.float64)
    g = np.exp(-(t[:, None, None] ** 2 + t[None, :, None] ** 2 + t[None, None, :] ** 2) / (2 * 1.5 ** 2))
    g /= g.sum()
    A, B = a.astype(np.float64), b.astype(np.float64)

    def filt(z):
        p = np.pad(z, r, mode="edge")
        out = np.zeros_like(z)
        h, w, c = z.shape
        for i in range(2 * r + 1):
            for j in range(2 * r + 1):
                for k in range(2 * r + 1):
                    out += g[i, j, k] * p[i:i + h, j:j + w, k:k + c]
        return out
    mx, my = filt(A), filt(B)
    sx, sy, sxy = filt(A * A) - mx * mx, filt(B * B) - my * my, filt(A * B) - mx * my
    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2
    return float(np.mean((2 * mx * my + c1) * (2 * sxy + c2) / ((mx * mx + my * my + c1) * (sx + sy + c2))))


def test_ssim_volume_3x3x3_by_definition():
    a = np.array([[[10, 200, 30], [40, 50, 60], [70, 80, 90]],
                  [[15, 25, 35], [250, 5, 65], [75, 85, 95]],
                  [[0, 255, 128], [64, 32, 16], [8, 4, 2]]], np.uint8)
    b = a.copy()
    b[1, 1] = [240, 20, 60]
    b[0, 2, 1] = 100
    got = metrics.ssim_volume(a, b)
    want = _volume_ssim_by_definition(a, b)
    assert abs(got - want) < 1e-12 and 0.3 < want < 0.999


def test_ssim_volume_larger_image_by_definition_and_differs_from_per_channel():
    rng = np.random.default_rng(8)
    a = rng.integers(0, 256, (16, 24, 3), dtype=np.uint8)       # both border strips and an interior
    b = np.clip(a.astype(int) + rng.integers(-60, 61, a.shape), 0, 255).astype(np.uint8)
    vol = metrics.ssim_volume(a, b)
    assert abs(vol - _volume_ssim_by_definition(a, b)) < 1e-12
    assert abs(vol - metrics.ssim(a, b)[0]) > 1e-3              # the window spans the channels


def test_ssim_volume_constants_symmetry_and_identity():
    a = np.full((5, 6, 3), 100, np.uint8)
    b = np.full((5, 6, 3), 110, np.uint8)
    c1 = (0.01 * 255) ** 2
    # flat images: no variance, SSIM is the luminance term
    assert metrics.ssim_volume(a, b) == pytest.approx((2 * 100 * 110 + c1) / (100 ** 2 + 110 ** 2 + c1), abs=1e-10)
    rng = np.random.default_rng(1)
    x = rng.integers(0, 256, (12, 13, 3), dtype=np.uint8)
    y = rng.integers(0, 256, (12, 13, 3), dtype=np.uint8)
    assert metrics.ssim_volume(x, x) == pytest.approx(1.0, abs=1e-12)
    assert metrics.ssim_volume(x, y) == pytest.approx(metrics.ssim_volume(y, x), abs=1e-14)


def test_ssim_volume_in_all_metrics_and_the_metric_list():
    a, b = _pairs8()[0][1:]
    lin = (a / 255.0) ** 2.2
    out, maps = judging.all_metrics(lin, a / 255.0, a, (b / 255.0) ** 2.2, b / 255.0, b)
    assert "ssim_volume" in metrics.METRICS and metrics.HIGHER_IS_BETTER["ssim_volume"]
    assert out["ssim_volume"] == pytest.approx(metrics.ssim_volume(a, b), abs=1e-14)
    assert "ssim_volume" not in maps


# -- the published definition, independent of the code (pins sigma 1.5) ---------------------------

def test_ssim_from_the_published_definition():
    """Wang et al. 2004 with an 11-tap Gaussian of sigma 1.5, population statistics, C1 = (0.01 L)^2,
    C2 = (0.03 L)^2, L = 255, per channel with mirrored borders, mean over the map less 5 pixels."""
    rng = np.random.default_rng(21)
    a = rng.integers(0, 256, (14, 17, 3), dtype=np.uint8)
    b = np.clip(a.astype(int) + rng.integers(-50, 51, a.shape), 0, 255).astype(np.uint8)
    t = np.arange(-5, 6, dtype=np.float64)
    g1 = np.exp(-t * t / (2 * 1.5 * 1.5))
    win = np.outer(g1, g1) / np.outer(g1, g1).sum()
    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2
    means, maps = [], []
    for c in range(3):
        x = np.pad(a[..., c].astype(np.float64), 5, mode="symmetric")
        y = np.pad(b[..., c].astype(np.float64), 5, mode="symmetric")
        m = np.zeros(a.shape[:2])
        for i in range(a.shape[0]):
            for j in range(a.shape[1]):
                px, py = x[i:i + 11, j:j + 11], y[i:i + 11, j:j + 11]
                mx, my = (win * px).sum(), (win * py).sum()
                vx, vy = (win * (px - mx) ** 2).sum(), (win * (py - my) ** 2).sum()
                cxy = (win * (px - mx) * (py - my)).sum()
                m[i, j] = (2 * mx * my + c1) * (2 * cxy + c2) / ((mx * mx + my * my + c1) * (vx + vy + c2))
        maps.append(m)
        means.append(m[5:-5, 5:-5].mean())
    got_mean, got_map = metrics.ssim(a, b)
    assert abs(got_mean - np.mean(means)) < 1e-9
    assert np.abs(got_map - np.mean(maps, axis=0)).max() < 1e-9


# -- errors and judge_run's maps -------------------------------------------------------------------

def test_bad_inputs_are_refused_with_the_size():
    a = np.zeros((8, 30, 3), np.uint8)
    with pytest.raises(ValueError, match="11x11"):
        metrics.ssim(a, a)
    with pytest.raises(ValueError, match="one shape"):
        metrics.flip(np.zeros((8, 8, 3)), np.zeros((8, 9, 3)), "LDR")
    with pytest.raises(ValueError, match="LDR"):
        metrics.flip(np.zeros((8, 8, 3)), np.zeros((8, 8, 3)), "XDR")
    with pytest.raises(ValueError, match="implementation"):
        metrics.ssim(a, a, impl="matlab")


class _Ref:
    def __init__(self, image):
        self.image = image


class _Display(DisplayTransform):
    """A display transform with a plain gamma (its output() splits as the real one's does)."""

    def encode(self, x):
        return np.clip(np.asarray(x, np.float64), 0, 1) ** (1 / 2.2)


def test_judge_run_keeps_maps_only_for_the_frames_asked():
    rng = np.random.default_rng(3)
    kept = [0, 1, 2]
    refs = {t: _Ref(rng.random((16, 24, 3)).astype(np.float32)) for t in kept}
    images = {t: np.clip(refs[t].image + 0.05, 0, 1).astype(np.float32) for t in kept}
    disp = {t: _Display(1.0, 1.0) for t in kept}
    ref8 = {t: np.round(disp[t].encode(refs[t].image) * 255).astype(np.uint8) for t in kept}
    res, maps = judging.judge_run(images, "linear", refs, disp, ref8, kept)
    assert set(maps) == {"ssim", "flip_ldr", "flip_hdr"} and set(res["per_frame"]) == {"0", "1", "2"}
    res2, maps2 = judging.judge_run(images, "linear", refs, disp, ref8, kept, maps_for={0, 2})
    assert set(maps2) == {0, 2} and np.array_equal(maps2[2]["ssim"], maps["ssim"])
    assert res2["per_frame"] == res["per_frame"]


def test_flip_memo_keeps_the_reference_half_and_changes_no_bit():
    """Judging several images against one reference reuses its half of FLIP (study.engine.judge): the maps
    are bit-identical to computing everything per pair, and the memo holds one entry per mode and
    HDR exposure."""
    rng = np.random.default_rng(3)
    ref = (rng.random((40, 57, 3)) ** 2 * 4).astype(np.float32)
    ref[5:12, 5:20] *= 20
    tests = [(ref * (1 + s * rng.standard_normal(ref.shape))).clip(0).astype(np.float32) for s in (0.1, 0.3)]
    memo = {}
    for x in tests:
        for mode, a, b in (("LDR", np.clip(ref / 4, 0, 1), np.clip(x / 4, 0, 1)), ("HDR", ref, x)):
            want_mean, want_map = F.flip(a, b, mode)
            got_mean, got_map = F.flip(a, b, mode, memo=memo)
            assert got_mean == want_mean and np.array_equal(got_map, want_map), mode
    n_exp = F.exposures(ref)[2]
    assert len([k for k in memo if k[0] == "HDR"]) == n_exp and len([k for k in memo if k[0] == "LDR"]) == 1


def test_one_image_against_several_references_changes_no_bit():
    """A technique frame is judged against the reference and its two halves with its own half of
    SSIM (moments) and FLIP (filtered planes) computed once, the references' kept in their memos
    across images (study.metrics.judging.all_metrics_against): every figure and map equals
    all_metrics pair by pair, bit for bit, and the shared halves are really shared."""
    rng = np.random.default_rng(11)
    h, w = 33, 50
    lin = [(rng.random((h, w, 3)) ** 2 * 3).astype(np.float32) for _ in range(2)]
    lin.append(lin[0].copy())          # a reference equal to another: its HDR exposures are shared
    refs = [(r, (r / (1 + r)) ** (1 / 2.2), np.round((r / (1 + r)) ** (1 / 2.2) * 255).astype(np.uint8), {})
            for r in lin]
    for s in (0.05, 0.3):
        x_lin = (lin[0] * (1 + s * rng.standard_normal(lin[0].shape))).clip(0).astype(np.float32)
        x_disp = (x_lin / (1 + x_lin)) ** (1 / 2.2)
        x8 = np.round(x_disp * 255).astype(np.uint8)
        got = judging.all_metrics_against(refs, x_lin, x_disp, x8, want_maps=[True, False, True])
        for (r_lin, r_disp, r8, _), (figs, maps), keep in zip(refs, got, (True, False, True)):
            want, want_maps = judging.all_metrics(r_lin, r_disp, r8, x_lin, x_disp, x8)
            assert figs == want
            assert set(maps) == (set(want_maps) if keep else set())
            for k in maps:
                assert np.array_equal(maps[k], want_maps[k]), k
        # a ghosting test's frames (Protocol.hdr False): the same figures, none in linear HDR
        ldr = judging.all_metrics_against(refs, x_lin, x_disp, x8, want_maps=[True, False, True], hdr=False)
        for (figs, maps), (full, full_maps) in zip(ldr, got):
            assert figs["flip_hdr"] is None and figs["relmse_hdr"] is None and "flip_hdr" not in maps
            assert figs == {**full, "flip_hdr": None, "relmse_hdr": None}
            assert set(maps) == set(full_maps) - {"flip_hdr"}
    assert all(any(k[0] == "ssim" for k in r[3]) for r in refs)     # the references' moments kept
    from study.metrics import flip as F
    xmemo = {}
    for r in refs:
        F.flip(r[0], x_lin, "HDR", memo=r[3], xmemo=xmemo)
    n0, n1 = (F.exposures(lin[i])[2] for i in (0, 1))
    assert len(xmemo) < n0 + n1 + n0                # the copy's exposures reuse the first's halves
    with pytest.raises(ValueError, match="NaN"):
        judging.all_metrics_against(refs, np.full_like(x_lin, np.nan), x_disp, x8)

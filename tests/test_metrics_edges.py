"""The metrics refuse what they cannot judge, naming what they expected (study.metrics.checks), and
take an explicit data range where the input has none; every public function is documented."""
import importlib
import inspect

import numpy as np
import pytest
from skimage.metrics import structural_similarity

from study.metrics import flip as F
from study.metrics import judging as J
from study.metrics import ssim as S
from study.metrics import ssim_against as SA
from study.metrics import suite as M
from study.metrics import temporal as T


def _pair8(h=24, w=32, seed=4):
    rng = np.random.default_rng(seed)
    a = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    b = np.clip(a.astype(int) + rng.integers(-30, 31, a.shape), 0, 255).astype(np.uint8)
    return a, b


# -- SSIM's data range ------------------------------------------------------------------------------

def test_ssim_of_float_images_without_a_data_range_is_refused_naming_the_input():
    a, b = _pair8()
    af, bf = a / 255.0, b / 255.0
    for call in (lambda: S.ssim(af, bf), lambda: M.ssim(af, bf), lambda: M.ssim(af, bf, impl="library"),
                 lambda: S.ssim_volume(af, bf), lambda: SA.ssim_against([af], bf)):
        with pytest.raises(ValueError) as err:
            call()
        msg = str(err.value)
        assert "data_range" in msg and "uint8" in msg and "float64" in msg, msg


def test_ssim_with_data_range_one_equals_the_pair_in_8_bit_and_scikit_image():
    a, b = _pair8()
    af, bf = a / 255.0, b / 255.0                    # the same images on a [0, 1] scale
    mean8, map8 = S.ssim(a, b)
    mean1, map1 = S.ssim(af, bf, data_range=1.0)
    # C1, C2 scale with L^2 as the statistics do: the same SSIM up to float64 rounding
    assert abs(mean1 - mean8) < 1e-12 and np.abs(map1 - map8).max() < 1e-12
    assert mean8 < 0.99                              # not a trivial pair
    ref_mean, ref_map = structural_similarity(af, bf, gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
                                              data_range=1.0, channel_axis=-1, K1=0.01, K2=0.03, full=True)
    assert abs(mean1 - ref_mean) < 1e-9 and np.abs(map1 - ref_map.mean(axis=-1)).max() < 1e-9
    assert M.ssim(af, bf, impl="library", data_range=1.0)[0] == pytest.approx(ref_mean, abs=1e-15)
    assert abs(S.ssim_volume(af, bf, data_range=1.0) - S.ssim_volume(a, b)) < 1e-12
    small = (slice(0, 7), slice(0, 9))               # the volume form's direct path (below the window)
    assert abs(S.ssim_volume(af[small], bf[small], data_range=1.0) - S.ssim_volume(a[small], b[small])) < 1e-12
    got = SA.ssim_against([af], bf, data_range=1.0)[0]
    assert abs(got[0] - mean1) < 1e-15 and abs(got[2] - S.ssim_volume(a, b)) < 1e-12
    # the wrong range is the silent failure this guards against: a [0, 1] pair judged as 0..255
    assert S.ssim(af, bf, data_range=255.0)[0] > 0.999


def test_ssim_refuses_values_wider_than_the_data_range_nan_and_bad_ranges():
    a, b = _pair8()
    with pytest.raises(ValueError, match=r"span \[0, 255\], more than data_range 1"):
        S.ssim(a.astype(np.float64), b.astype(np.float64), data_range=1.0)
    af = a / 255.0
    bad = af.copy()
    bad[2, 3, 1] = np.nan
    with pytest.raises(ValueError, match="test image holds 1 NaN/Inf"):
        S.ssim(af, bad, data_range=1.0)
    bad[2, 3, 1] = np.inf
    with pytest.raises(ValueError, match="reference holds 1 NaN/Inf"):
        S.ssim(bad, af, data_range=1.0)
    for r in (0, -1.0, np.nan, "one"):
        with pytest.raises(ValueError, match="data_range must be"):
            S.ssim(af, af, data_range=r)


def test_ssim_names_mismatched_shapes_and_dtypes():
    a, b = _pair8()
    with pytest.raises(ValueError) as err:
        S.ssim(a, b[:, :31])
    assert "24x32x3" in str(err.value) and "24x31x3" in str(err.value)
    with pytest.raises(ValueError, match="uint8 and float64"):
        S.ssim(a, b / 255.0, data_range=1.0)
    with pytest.raises(ValueError, match="uint16"):
        S.ssim(a.astype(np.uint16), b.astype(np.uint16))
    with pytest.raises(ValueError, match="H x W x 3"):
        S.ssim(a[..., 0], b[..., 0])


# -- FLIP's input ranges ----------------------------------------------------------------------------

def test_flip_ldr_refuses_values_outside_0_1_and_reads_uint8_as_value_over_255():
    a, b = _pair8(16, 20)
    af, bf = a.astype(np.float32) / np.float32(255), b.astype(np.float32) / np.float32(255)
    for bad, words in ((bf * 1.2, "test image's values span [0, 1.2]"), (bf - 0.1, "span [-0.1")):
        with pytest.raises(ValueError) as err:
            F.flip(af, bad, "LDR")
        assert words in str(err.value) and "[0, 1] or uint8" in str(err.value) and "'HDR'" in str(err.value)
        with pytest.raises(ValueError, match=r"\[0, 1\]"):
            M.flip(bad, af, "LDR", impl="library")
    with pytest.raises(ValueError, match="uint16"):
        F.flip(a.astype(np.uint16), b.astype(np.uint16), "LDR")
    with pytest.raises(ValueError, match="reference is uint8 and the test image float32"):
        F.flip(a, bf, "LDR")
    m8, e8 = F.flip(a, b, "LDR")
    mf, ef = F.flip(af, bf, "LDR")
    assert m8 == mf and np.array_equal(e8, ef) and mf > 0.01


def test_flip_refuses_nan_and_negative_hdr_and_names_shapes():
    rng = np.random.default_rng(9)
    a = (rng.random((16, 20, 3)) * 4).astype(np.float32)
    b = a * 1.1
    for mode, x in (("LDR", a / 4), ("HDR", a)):
        bad = x.copy()
        bad[0, 0, 0] = np.nan
        with pytest.raises(ValueError, match=f"{mode}-FLIP: the test image holds 1 NaN/Inf"):
            F.flip(x, bad, mode)
    neg = b.copy()
    neg[3, 4, 2] = -0.5
    with pytest.raises(ValueError, match=r"HDR-FLIP: the test image holds negative values \(down to -0.5\)"):
        F.flip(a, neg, "HDR")
    with pytest.raises(ValueError, match="reference holds negative"):
        F.exposures(neg)
    with pytest.raises(ValueError, match="HDR-FLIP: the reference is uint8"):
        F.flip(np.zeros((16, 20, 3), np.uint8), np.zeros((16, 20, 3), np.uint8), "HDR")
    with pytest.raises(ValueError) as err:
        F.flip(a, b[:15], "HDR")
    assert "16x20x3" in str(err.value) and "15x20x3" in str(err.value)
    with pytest.raises(ValueError, match="ppd must be a finite number > 0"):
        F.flip(a / 4, b / 5, "LDR", ppd=-3)


# -- the 8-bit and linear figures, the suite ------------------------------------------------------

def test_suite_figures_refuse_what_they_cannot_judge():
    a, b = _pair8(8, 8)
    for fn in (M.mse, M.snr):
        with pytest.raises(ValueError, match="uint8 8-bit display images expected, got float64"):
            fn(a / 255.0, b / 255.0)
        with pytest.raises(ValueError) as err:
            fn(a, b[:7])
        assert "8x8x3" in str(err.value) and "7x8x3" in str(err.value)
    for m in (-1.0, float("nan")):
        with pytest.raises(ValueError, match="PSNR: the MSE must be"):
            M.psnr_from_mse(m)
    lin = a / 255.0
    bad = lin.copy()
    bad[1, 1, 1] = np.inf
    with pytest.raises(ValueError, match="relMSE: the test image holds 1 NaN/Inf"):
        M.relmse(lin, bad)
    with pytest.raises(ValueError, match="relMSE: the reference is uint8"):
        M.relmse(a, lin)
    acc = T.TemporalInstability()
    with pytest.raises(ValueError, match="reference frame is 8x8x3, the technique frame 7x8x3"):
        acc.add(a, b[:7])
    acc.add(a, b)
    with pytest.raises(ValueError, match="frame 1 is"):
        acc.add(a[:7], b[:7])
    with pytest.raises(ValueError, match="2 reference frames and 1 technique frames"):
        T.temporal_instability([a, a], [b])


def test_all_metrics_checks_each_image_by_name():
    a, b = _pair8(12, 12)
    lin_a, lin_b = (a / 255.0) ** 2.2, (b / 255.0) ** 2.2
    good = (lin_a, a / 255.0, a, lin_b, b / 255.0, b)
    J.all_metrics(*good)
    # 8-bit display images are read as value / 255 (as FLIP reads them); an 8-bit one against a float one is refused
    f32 = [v.astype(np.float32) / np.float32(255) for v in (a, b)]
    assert J.all_metrics(lin_a, a, a, lin_b, b, b)[0] == J.all_metrics(lin_a, f32[0], a, lin_b, f32[1], b)[0]
    with pytest.raises(ValueError, match="the reference is uint8 and the test image float64"):
        J.all_metrics(lin_a, a, a, lin_b, b / 255.0, b)
    cases = [
        (1, lin_a * 4, "the reference display image's values span [0, 4]"),   # linear passed as display
        (4, b * 1.0, "technique display image's values span [0, 255]"),
        (3, lin_b.astype(np.int32), "the technique image is int32; a linear float image expected"),
        (0, lin_a[:11], "the reference image is 11x12x3, the technique 8-bit image 12x12x3"),
        (5, b[:, :11], "the reference 8-bit image is 12x12x3, the technique 8-bit image 12x11x3"),
    ]
    for i, bad, words in cases:
        args = list(good)
        args[i] = bad
        with pytest.raises(ValueError) as err:
            J.all_metrics(*args)
        assert words in str(err.value), str(err.value)
        refs = [(*args[:3], {})]
        with pytest.raises(ValueError) as err:
            J.all_metrics_against(refs, *args[3:])
        assert words in str(err.value), str(err.value)


# -- documentation ----------------------------------------------------------------------------------

MODULES = ("suite", "judging", "temporal", "ssim", "ssim_window", "ssim_passes", "ssim_against", "flip", "flip_colour",
           "flip_passes", "filters", "uncertainty", "video", "checks")


def _public():
    for name in MODULES:
        mod = importlib.import_module(f"study.metrics.{name}")
        for attr, obj in vars(mod).items():
            if attr.startswith("_") or getattr(obj, "__module__", None) != mod.__name__:
                continue
            if inspect.isfunction(obj):
                yield f"{name}.{attr}", obj
            elif inspect.isclass(obj):
                yield f"{name}.{attr}", obj
                for m, f in vars(obj).items():
                    if inspect.isfunction(f) and not m.startswith("_"):
                        yield f"{name}.{attr}.{m}", f


def test_every_public_function_of_the_metrics_has_a_numpydoc_docstring():
    missing = []
    for name, obj in _public():
        doc = inspect.getdoc(obj) or ""
        if not doc:
            missing.append(f"{name}: no docstring")
            continue
        if inspect.isclass(obj):
            continue
        sig = inspect.signature(obj)
        params = [p for p in sig.parameters if p not in ("self", "cls")]
        if params and "Parameters\n----------" not in doc:
            missing.append(f"{name}: no Parameters section")
        described = set()
        section = doc.split("Parameters\n----------\n", 1)[-1].split("\n\n")[0] if params else ""
        for line in section.splitlines():
            if line and not line[0].isspace():     # "name : type" or "a, b : type"
                described |= {n.strip() for n in line.split(" : ")[0].split(",")}
        for p in params:
            if p not in described:
                missing.append(f"{name}: parameter {p} not described")
        returns_none = sig.return_annotation in (None, "None")
        if not returns_none and "Returns\n-------" not in doc:
            missing.append(f"{name}: no Returns section")
    assert not missing, "\n".join(missing)
    refs = {"ssim": "Wang", "flip": "Andersson", "video": "Mantiuk"}
    for name, author in refs.items():
        doc = importlib.import_module(f"study.metrics.{name}").__doc__
        assert "References\n----------" in doc and author in doc, name

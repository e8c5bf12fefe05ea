import numpy as np
import pytest

from display import DisplayTransform, luminance, psnr


def test_reinhard_by_hand():
    # Two grey pixels of luminance 1 and 4; delta = 0 makes the log-average exactly 2.
    ref = np.array([[[1.0, 1.0, 1.0], [4.0, 4.0, 4.0]]])
    d = DisplayTransform.from_reference(ref, key=0.18, delta=0.0, white=1.5)
    assert d.log_average == pytest.approx(2.0)
    l = 0.18 / 2.0 * 4.0                                   # scaled luminance of the bright pixel
    want = l * (1 + l / 1.5 ** 2) / (1 + l)
    np.testing.assert_allclose(d.tonemap(ref)[0, 1], [want] * 3, rtol=1e-12)
    # sRGB encoding of the tone-mapped value
    enc = want * 12.92 if want <= 0.0031308 else 1.055 * want ** (1 / 2.4) - 0.055
    np.testing.assert_allclose(d.encode(ref)[0, 1], [enc] * 3, rtol=1e-9)
    assert d.to_8bit(ref)[0, 1, 0] == round(enc * 255)


def test_default_white_maps_the_brightest_pixel_to_white_and_hue_is_kept():
    ref = np.array([[[0.2, 0.4, 0.1], [2.0, 2.0, 2.0]]])
    d = DisplayTransform.from_reference(ref)
    out = d.tonemap(ref)
    assert luminance(out[0, 1]) == pytest.approx(1.0)
    np.testing.assert_allclose(out[0, 0] / out[0, 0, 1], ref[0, 0] / ref[0, 0, 1])


def test_psnr_infinite_for_identical_and_nan_reference_refused():
    a = np.random.default_rng(0).random((4, 4, 3))
    assert psnr(a, a) == float("inf")
    assert psnr(a, a + 0.1) == pytest.approx(20.0)
    with pytest.raises(ValueError, match="NaN"):
        DisplayTransform.from_reference(np.full((2, 2, 3), np.nan))


def test_a_study_process_encodes_without_colours_plotting_stack_and_can_still_plot():
    """study/__init__ defers colour.plotting (matplotlib, networkx: 1.5 s of every process that
    encodes): the encoding is colour's own, and colour.plotting still loads on first use."""
    import subprocess
    import sys
    code = ("import sys, numpy as np\n"
            "import study, colour\n"
            "from display import DisplayTransform\n"
            "d = DisplayTransform.from_reference(np.array([[[0.2, 0.4, 0.1], [2.0, 2.0, 2.0]]]))\n"
            "x = d.encode(np.array([[[0.5, 0.25, 0.125]]]))\n"
            "assert np.array_equal(x, colour.cctf_encoding(d.tonemap(np.array([[[0.5, 0.25, 0.125]]])), function='sRGB'))\n"
            "print('before', 'matplotlib' in sys.modules)\n"
            "f = colour.plotting.plot_single_colour_swatch\n"
            "import colour.plotting as P\n"
            "print('after', 'matplotlib' in sys.modules, P is colour.plotting, callable(f))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["before", "False", "after", "True", "True", "True"], out.stdout

"""The maps' honesty marks (study.reporting.map_noise): a map is painted exactly where the
reference's own display-domain noise exceeds the map's colour step, and the thresholds are what the
stated rule gives."""
from __future__ import annotations

import json

import numpy as np
import pytest

from study.reporting import map_noise as M


@pytest.mark.parametrize("kind", M.KINDS)
def test_threshold_is_the_smallest_noise_that_moves_the_map_a_colour_step(kind):
    """At the grey and noise THRESHOLDS names, reference noise of SE D moves the map by a step (RMS)
    and 3 % less does not; nowhere else among the calibration's greys does 3 % less reach a step."""
    d, grey, noise = M.THRESHOLDS[kind]
    z = M.noise_fields()
    step = 1.0 / M.MAP_STEPS
    assert M._moves(kind, grey, d, z[noise]) >= step
    for g in M.GREYS:
        for name, field in z.items():
            assert M._moves(kind, g, 0.97 * d, field) < step, (g, name)


class _Ref:
    def __init__(self, image, stderr):
        self.image, self.stderr = image, stderr


def _jacobian(disp, rgb: np.ndarray) -> np.ndarray:
    """(N, 3, 3) central differences of the display transform (display_se takes forward ones)."""
    jac = np.empty((len(rgb), 3, 3))
    for k in range(3):
        h = 1e-4 * np.maximum(rgb[:, k], 1e-3)
        lo, hi = rgb.copy(), rgb.copy()
        lo[:, k] -= h
        hi[:, k] += h
        jac[:, :, k] = (disp.encode(hi) - disp.encode(lo)) / (2 * h[:, None])
    return jac


@pytest.mark.parametrize("kind", M.KINDS)
def test_exactly_the_pixels_whose_reference_noise_exceeds_the_step_are_marked(kind):
    """A tiny reference with a known display SE per pixel: 0 on most pixels, and on some just over
    or well over the map's threshold, on others just or well under it."""
    from display import DisplayTransform
    h, w = 9, 12
    rng = np.random.default_rng(3)
    image = rng.uniform(0.05, 2.0, (h, w, 3)).astype(np.float32)
    disp = DisplayTransform.from_reference(image)
    d = M.threshold_lsb(kind)
    target = np.zeros((h, w))                       # display SE, LSB, of the worst channel
    over = [(1, 2, 1.05), (4, 7, 2.0), (8, 11, 10.0), (0, 0, 33.0)]
    under = [(2, 2, 0.95), (5, 5, 0.5), (7, 1, 0.1)]
    for y, x, f in over + under:
        target[y, x] = f * d
    # the linear SE that gives that display SE: the same relative SE on every channel
    jac = _jacobian(disp, image.reshape(-1, 3).astype(np.float64))
    unit = np.sqrt((jac ** 2 * image.reshape(-1, 1, 3).astype(np.float64) ** 2).sum(-1)).max(-1) * 255.0
    rel = target.reshape(-1) / unit
    stderr = (image.reshape(-1, 3) * rel[:, None]).reshape(h, w, 3)
    se = M.reference_se_lsb(_Ref(image, stderr), disp)
    assert np.allclose(se, target, rtol=1e-3, atol=1e-6)
    marked = M.marks(se, kind)
    assert sorted(zip(*np.nonzero(marked))) == sorted((y, x) for y, x, _ in over)


def test_painting_shows_only_the_marked_pixels_in_a_colour_no_map_uses():
    from study.reporting.encode import magma
    ramp = np.linspace(0, 1, 4096)
    assert not np.any(np.all(magma(ramp) == M.MARK_RGB, axis=-1))     # the FLIP map's palette
    assert len(set(M.MARK_RGB)) > 1                                     # not a grey, the SSIM map's
    grey = np.arange(12 * 9, dtype=np.uint8).reshape(9, 12)
    marked = np.zeros((9, 12), bool)
    marked[[0, 4, 8], [0, 7, 11]] = True
    out = M.paint(grey, marked)
    assert np.all(out[marked] == M.MARK_RGB)
    assert np.array_equal(out[~marked], np.repeat(grey[..., None], 3, -1)[~marked])
    col = magma(grey / 107.0)
    assert np.array_equal(M.paint(col, marked)[~marked], col[~marked])


def test_bad_se_is_refused():
    with pytest.raises(ValueError, match="finite H x W"):
        M.marks(np.array([[1.0, np.nan]]), "ssim")
    with pytest.raises(ValueError, match="map kind"):
        M.threshold_lsb("psnr")

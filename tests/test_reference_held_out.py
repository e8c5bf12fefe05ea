"""The adaptive reference's stopping bias, and the held-out estimator that removes it:
the loop of references.render run on pixels whose value is known exactly."""
import numpy as np
import pytest

from references.render import converge
from references.result import ReferenceError


class _Bernoulli:
    """A tracer whose every sample of pixel i is 1 with probability p[i], else 0 (all three
    channels): the pixel's true value is p[i], and a set's sum is a binomial draw."""

    def __init__(self, p):
        self.p = p

    def chunked(self, pix, r, a, rng, groups=None):
        hits = rng.binomial(a, self.p[pix][:, None], size=(len(pix), r)).astype(np.float64)
        rgb = lambda x: np.repeat(x[..., None], 3, -1)   # noqa: E731
        g = groups or r        # the extremes of runs of r / g consecutive sets, as the tracer's
        lo, hi = (x.reshape(len(pix), g, r // g, 3) for x in (rgb((hits == a) * 1.0), rgb((hits > 0) * 1.0)))
        yield pix, rgb(hits), lo.min(axis=2), hi.max(axis=2)


def _bias(held_out: bool, p: float = 0.1, w: int = 200, seed: int = 0):
    """The pixels' mean error in units of their SE, and its standard deviation (1 / sqrt(n))."""
    truth = np.full(w * w, p)
    truth[:w] = 1.0        # one row that always hits: the display's white, as a lit scene's highlight
    ref = converge(_Bernoulli(truth), w, w, "bernoulli", se_bound_lsb=8.0, target_noise_db=0.0, spp_per_pass=2,
                   min_passes=4, replicates=32, max_spp=1 << 16, seed=seed, held_out=held_out)
    x, se = ref.image[1:, :, 0].astype(np.float64), ref.stderr[1:, :, 0].astype(np.float64)
    return float((x - p).mean() / np.sqrt((se ** 2).mean())), 1 / np.sqrt(x.size), ref


def test_stopping_on_the_samples_biases_the_mean_and_held_out_samples_do_not():
    """Every pixel's samples are Bernoulli(0.1). Where the spread moves with the value (here the
    display transform's slope: a pixel with more hits has a lower display SE and stops sooner), a
    mean of the samples that decided is biased: +0.05 of its SE, 10 sd of the mean over 40 000
    pixels. The mean of samples no decision saw is within 3 sd of the truth."""
    plain, sd, ref = _bias(False)
    assert plain > 6 * sd, (plain, sd)
    held, sd, held_ref = _bias(True)
    assert abs(held) < 3 * sd, (held, sd)
    assert held_ref.held_out and not ref.held_out
    # its halves are halves of the held-out samples: their mean is the value
    a, b = held_ref.halves()
    assert np.abs((a + b) / 2 - held_ref.image).max() < 1e-6
    # what the held-out share costs here: the deciding quarter, and decisions from fewer samples
    assert ref.spp < held_ref.spp < 2 * ref.spp, (ref.spp, held_ref.spp)


def test_held_out_needs_a_deciding_share_and_two_halves_of_the_rest():
    from study.engine.tasks import load_scene
    from references.render import render_reference
    with pytest.raises(ReferenceError, match="held_out needs min_passes a multiple of 4 and replicates of 8"):
        render_reference(load_scene("pipe"), 0, 8, 8, min_passes=2, held_out=True)
    with pytest.raises(ReferenceError, match="replicates of 8"):
        render_reference(load_scene("pipe"), 0, 8, 8, replicates=12, held_out=True)

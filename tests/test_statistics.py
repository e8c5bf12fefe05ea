"""The statistics the tables print: Spearman's rho of two rankings (the reproduction table) and the
percentile-bootstrap interval of a mean (ab, the findings). The figures they give today are pinned,
the rank correlation agrees with the closed form for rankings without ties, and the bootstrap with
scipy.stats.bootstrap (pinned, an independent implementation) resample for resample."""
import itertools
import math

import numpy as np
import pytest

from study.reporting.intervals import bootstrap_ci
from study.reporting.summaries import rank, spearman


def closed_form(a, b):
    common = [x for x in a if x in b]
    ra = {x: i for i, x in enumerate(x for x in a if x in common)}
    rb = {x: i for i, x in enumerate(x for x in b if x in common)}
    n = len(common)
    return 1 - 6 * sum((ra[x] - rb[x]) ** 2 for x in common) / (n * (n * n - 1))


def test_spearman_hand_computed():
    assert spearman(list("abcde"), list("abdce")) == pytest.approx(0.9, abs=1e-12)    # one swap: 1 - 6*2/120
    assert spearman(list("abcde"), list("edcba")) == pytest.approx(-1.0, abs=1e-12)
    assert spearman(list("ab"), list("ab")) == pytest.approx(1.0, abs=1e-12)
    # labels one ranking lacks are left out: over a, b, c the order is reversed
    assert spearman(list("abcx"), list("ycba")) == pytest.approx(-1.0, abs=1e-12)
    assert math.isnan(spearman(list("a"), list("a")))
    assert math.isnan(spearman(list("ab"), list("cd")))


def test_spearman_agrees_with_the_closed_form_on_every_ranking_of_five():
    base = list("abcde")
    for perm in itertools.permutations(base):
        assert spearman(base, list(perm)) == pytest.approx(closed_form(base, list(perm)), abs=1e-12)


def test_rank_orders_best_first():
    assert rank({"No AA": 30.0, "TAA": 40.0, "FXAA": 35.0}) == ["TAA", "FXAA", "No AA"]


def test_bootstrap_interval_pinned():
    d = np.array([0.3, -0.1, 0.5, 0.2, 0.9, -0.4, 0.1, 0.6])
    lo, hi = bootstrap_ci(d)
    assert (lo, hi) == pytest.approx((0.0121875, 0.5375), abs=1e-12)
    assert lo < d.mean() < hi
    assert bootstrap_ci(d) == (lo, hi)                       # fixed seed: the same figures every run
    assert bootstrap_ci(np.arange(10.0)) == pytest.approx((2.7, 6.3), abs=1e-12)


@pytest.mark.parametrize("n", [2, 8, 25, 700])
def test_bootstrap_equals_scipys(n):
    from scipy import stats
    d = np.random.default_rng(n).normal(0.2, 1.0, n)
    ref = stats.bootstrap((d,), np.mean, n_resamples=2000, confidence_level=0.95, method="percentile",
                          random_state=np.random.default_rng(0)).confidence_interval
    assert bootstrap_ci(d) == pytest.approx((ref.low, ref.high), rel=1e-12, abs=1e-14)
    if n > 2:      # two values: the interval is their range whatever the draws
        assert bootstrap_ci(d, seed=1) != bootstrap_ci(d)    # the seed is used


def test_bootstrap_degenerate_cases():
    assert bootstrap_ci(np.array([1.5])) is None             # one pair: no interval
    assert bootstrap_ci(np.array([-2.0, -2.0, -2.0])) == (-2.0, -2.0)   # a technique against itself
    rng = np.random.default_rng(1)
    small = bootstrap_ci(rng.normal(1.0, 1.0, 20))
    large = bootstrap_ci(rng.normal(1.0, 1.0, 2000))
    assert large[1] - large[0] < (small[1] - small[0]) / 4  # ~1/sqrt(n): 10x the width at 100x the pairs
    assert large[0] < 1.0 < large[1]

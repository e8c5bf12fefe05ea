"""Precision set by the figures: each scene's references refined until the reference's share of
every figure's uncertainty is within its tolerance (issue 20).

A reference's noise matters only through the figures it is judged into, and those figures'
uncertainty is measured, not assumed, in two parts:
  - the noise the two halves of a reference see (study.metrics.uncertainty): random, and the
    bias that scales with the noise's variance, which the jackknife removes;
  - what both halves share (`drift`): a sliver every sample of a pixel missed, the stopping
    rule's bias. Measured at 1600x900 on hairball_lit, 2-LSB references gave every figure
    0.2-0.6 % less MSE than 0.5-LSB ones while the halves said +-0.03 %; it shrinks with the
    bound, so the change of a figure from the previous, twice as coarse, bound estimates it.
So a scene starts at a coarse per-pixel bound (`start_bound_lsb`, level 0) and its references
are rendered again at half the bound (about 4x the samples where the spread of the samples
decides, 2x where the unseen-feature floor does) until, at some level >= 1, every figure of
every test (every judged frame of every technique, every metric) has both its halves'
uncertainty and its change from the level before within its tolerance, or the bound is
`finest_bound_lsb`. A figure's stated uncertainty is the sum of the two. The
coarser levels' work is kept in the cache (a re-run replays the same decisions from it) and costs
at most 1/3 of the level the scene ends at. Figures still over their tolerance at the finest
level are reported, never hidden.

rule = "per_pixel" is the former rule: every reference at the [reference] bound, whatever the figures.
"""
from __future__ import annotations

import math

from study.metrics import uncertainty as U


def figures_of(res) -> dict:
    """(label, frame, metric) -> (value, halves' uncertainty) of every finite figure of a
    TestResult (the temporal RMS under frame None)."""
    out = {}
    for l, per in res.per_frame.items():
        for f, figs in per.items():
            us = res.uncertainty.get(l, {}).get(f, {})
            out.update({(l, f, m): (v, us.get(m) or 0.0) for m, v in figs.items() if v is not None and math.isfinite(v)})
        t = res.temporal.get(l)
        if t is not None and math.isfinite(t):
            out[(l, None, "temporal")] = (t, res.temporal_u.get(l) or 0.0)
    return out


def over_tolerance(figures: dict, tolerances: dict) -> list[tuple]:
    """(*key, uncertainty, tolerance) of every figure of a `figures_of` dict whose reference
    uncertainty exceeds its tolerance, worst first."""
    out = [(*k, u, tol) for k, (v, u) in figures.items()
           for tol in [U.excess(k[-1], v, u, tolerances)] if tol is not None]
    return sorted(out, key=lambda x: -(x[-2] / x[-1] if x[-1] else math.inf))


def drift(now: dict, before: dict, tolerances: dict) -> tuple[dict, list]:
    """What the halves cannot see: a bias both halves share (a sliver every sample of a pixel
    missed, the stopping rule's), which shrinks as the bound does. The change of each figure from
    the previous, twice as coarse, bound estimates what is left of it (exactly, if it shrinks in
    proportion to the bound), beyond what the two references' own noise explains (their halves'
    uncertainties). Returns ((label, frame, metric) -> that excess, the figures whose excess is
    over their tolerance, as over_tolerance lists them)."""
    change, over = {}, []
    for k, (v, u) in now.items():
        if k in before:
            v0, u0 = before[k]
            d = max(0.0, abs(v - v0) - u - u0)
            change[k] = d
            tol = U.tolerance(k[-1], v, tolerances)
            if tol is not None and d > tol:
                over.append((*k, d, tol))
    return change, over

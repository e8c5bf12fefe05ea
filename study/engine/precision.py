"""Precision set by the figures: each test's references refined until the reference's share of
every figure's uncertainty is within its tolerance (issue 20).

A reference's noise matters only through the figures it is judged into, and those figures'
uncertainty is measured, not assumed, in two parts:
  - the noise the two halves of a reference see (study.metrics.uncertainty): random, and the
    bias that scales with the noise's variance, which the jackknife removes;
  - what both halves share, or they understate (`drift`): a sliver every sample of a pixel
    missed, a residual the jackknife leaves where 8-bit rounding makes a figure's dependence on
    the noise non-linear, and, while references were the mean of the samples that decided their
    counts, the stopping rule's bias: on hairball_lit (160x90) the jackknifed MSE of a blurred
    image was 1.2 % high at 8 LSB, 0.07 % at 2 (scripts/reference_bias.py), which drove most
    1600x900 tests to 0.125 LSB. The figures' rule's references are now held out
    (references.estimates: unbiased): the same figure is 220.76 +- 0.49 at 8 LSB against 220.87.
    What is left shrinks with the bound (taken in proportion), so the change of a figure from a
    coarser bound b0 to the bound b estimates what is left of it at b: change x b / (b0 - b).
Each test (a scene under one protocol: its static test, each ghosting protocol) has its own bound,
since their figures need different precisions: a near-converged SSAA 16x on pipe (MSE 0.2) needs
~0.25 LSB, a ghosting TAA (MSE ~10^2) far less, and a sequence's every frame pays for it.
  1. A probe: every reference of the test at `start_bound_lsb` (8 LSB by default, a few times the
     pilot's samples).
  2. A test whose every figure is within its tolerance at the probe is settled there (`confirm`:
     rendered once more at the next bound, to measure the drift as well). Otherwise the bound the
     figures need, predicted from the probe: a figure's halves' uncertainty falls in proportion to
     the bound, so each asks for b tol / (u x MARGIN); the test's references are rendered again at
     the largest power-of-two fraction of the start below what every figure asks, at least one
     level finer.
  3. Checked there: every figure's halves' uncertainty plus its drift from the bound before within
     its tolerance, else predicted again from that sum (at least one level finer), down to
     `finest_bound_lsb`. A figure's stated uncertainty is that sum; figures still over their
     tolerance at the finest bound are reported, never hidden.
The probe's work (the coarser bounds') is kept in the cache (a re-run replays the same decisions).

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


MARGIN = 1.5      # a figure's halves' uncertainty is one draw (about 2 sd, with a spread): aim below


def drift(now: dict, before: dict, tolerances: dict, scale: float = 1.0) -> tuple[dict, list]:
    """What the halves cannot see: a bias both halves share, which shrinks as the bound does. The
    change of each figure from a coarser bound, beyond what the two references' own noise explains
    (their halves' uncertainties), times `scale` = b / (b0 - b) estimates what is left of it at the
    bound b (exactly, if it shrinks in proportion to the bound). Returns ((label, frame, metric) ->
    that estimate, the figures whose estimate is over their tolerance, as over_tolerance lists them)."""
    change, over = {}, []
    for k, (v, u) in now.items():
        if k in before:
            v0, u0 = before[k]
            d = max(0.0, abs(v - v0) - u - u0) * scale
            change[k] = d
            tol = U.tolerance(k[-1], v, tolerances)
            if tol is not None and d > tol:
                over.append((*k, d, tol))
    return change, over


def needed_level(figures: dict, tolerances: dict, level: int, most: int) -> int:
    """The level (bound start / 2**level) a test's figures ask for, from their uncertainties at
    `level` ((value, uncertainty) by key, as figures_of gives, the drift included): u falls in
    proportion to the bound, so a figure asks for log2(u x MARGIN / tol) levels more. At least
    level + 1, at most `most`."""
    want = level + 1
    for k, (v, u) in figures.items():
        tol = U.tolerance(k[-1], v, tolerances)
        if tol is None or tol <= 0 or not u:     # a relative tolerance on a figure of 0: no scale to ask for
            continue
        want = max(want, level + math.ceil(math.log2(u * MARGIN / tol)))
    return min(want, most)


def decide(now: dict, before: dict, levels: dict, precision, over: dict, drifts: dict) -> tuple[dict, set]:
    """One round of the rule. `now`: test -> its figures ((value, halves' uncertainty) by key, as
    figures_of gives) at the bound of `levels` (test -> level); `before`: test -> (bound, figures)
    of the round before, updated here. A test whose bound did not change is left as decided; for
    the others `over` (test -> the figures over tolerance) and `drifts` (test -> figure -> drift)
    are set. Returns (test -> the level to render next, the tests judged this round)."""
    finer, judged = {}, set()
    for k in sorted(now):
        level, figs, b = levels.get(k, 0), now[k], precision.bound(levels.get(k, 0))
        if k in before and before[k][0] == b:
            continue                       # not refined this round: as decided before
        judged.add(k)
        if level > 0 and k in before:      # what both halves share: the change from the coarser bound
            b0 = before[k][0]
            change, _ = drift(figs, before[k][1], precision.tolerances, b / (b0 - b))
            drifts[k] = change
            figs = {f: (v, u + change.get(f, 0.0)) for f, (v, u) in figs.items()}
        over[k] = over_tolerance(figs, precision.tolerances)
        if (over[k] or (level == 0 and precision.confirm)) and level < precision.levels():
            finer[k] = needed_level(figs, precision.tolerances, level, precision.levels())
        before[k] = (b, now[k])
    return finer, judged


def to_record(levels: dict, tried: dict, over: dict, drifts: dict) -> dict:
    """A study's decisions as JSON: each test's final level, the bounds it was rendered to, its
    figures over tolerance and its drifts. A study whose probe plans the same tasks under the same
    rule decides the same (every task is deterministic), so it replays these instead of planning
    and reading every round again."""
    return {"tests": [{"test": list(k), "level": levels.get(k, 0), "tried": list(tried[k]),
                       "over": [list(x) for x in over.get(k, [])],
                       "drift": [[*f, d] for f, d in drifts.get(k, {}).items()]} for k in sorted(tried)]}


def from_record(rec: dict) -> tuple[dict, dict, dict, dict]:
    """(levels, tried, over, drifts) of a to_record record."""
    levels, tried, over, drifts = {}, {}, {}, {}
    for t in rec["tests"]:
        k = tuple(t["test"])
        levels[k], tried[k] = int(t["level"]), list(t["tried"])
        over[k] = [tuple(x) for x in t["over"]]
        drifts[k] = {tuple(d[:-1]): d[-1] for d in t["drift"]}
    return levels, tried, over, drifts

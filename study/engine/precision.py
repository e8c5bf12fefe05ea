"""Precision set by the figures: each scene's references refined until the reference's share of
every figure's uncertainty is within its tolerance (issue 20).

A reference's noise matters only through the figures it is judged into, and those figures'
uncertainty (study.metrics.uncertainty) is measured, not assumed. So a scene starts at a coarse
per-pixel bound (`start_bound_lsb`, level 0) and, while any figure of any of its tests (every
judged frame of every technique, every metric) has an uncertainty above its tolerance, its
references are rendered again at half the bound (about 4x the samples where the spread of the
samples decides, 2x where the unseen-feature floor does), down to `finest_bound_lsb`. The
coarser levels' work is kept in the cache (a re-run replays the same decisions from it) and costs
at most 1/3 of the level the scene ends at. Figures still over their tolerance at the finest
level are reported, never hidden.

rule = "per_pixel" is the former rule: every reference at the [reference] bound, whatever the figures.
"""
from __future__ import annotations

import math

from study.config.precision import Precision  # noqa: F401  (the settings, the study file's [precision])
from study.metrics import uncertainty as U


def over_tolerance(res, tolerances: dict) -> list[tuple]:
    """(label, frame, metric, uncertainty, tolerance) of every figure of a TestResult whose
    reference uncertainty exceeds its tolerance, worst first."""
    out = []
    for label, per in res.per_frame.items():
        for f, figs in per.items():
            us = res.uncertainty.get(label, {}).get(f, {})
            for m, ratio in U.over_tolerance(figs, us, tolerances).items():
                out.append((label, f, m, us[m], us[m] / ratio if ratio else 0.0))
        t, tu = res.temporal.get(label), res.temporal_u.get(label)
        if tu is not None:
            for m, ratio in U.over_tolerance({"temporal": t}, {"temporal": tu}, tolerances).items():
                out.append((label, None, m, tu, tu / ratio))
    return sorted(out, key=lambda x: -(x[3] / x[4] if x[4] else math.inf))

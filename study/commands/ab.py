"""Scripted A/B comparison of two technique configurations (the study's make-style runs).

Pairs are frames of the converged protocols: the static test's frame after its full history and
every frame of the warm ghosting test, of every scene. For each metric we report the mean paired
difference B - A with a 95 % bootstrap confidence interval (2000 resamples, fixed seed, so the same
runs print the same figures), per scene and overall, and the difference in cost per frame. With a
single pair there is no interval: it is reported as None (null in JSON) with n = 1. `worse_by` says
how much worse B is than A.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from study.config.techniques import TechniqueConfig
from study.engine.runner import Study
from study.metrics.suite import HIGHER_IS_BETTER
from study.reporting.intervals import bootstrap_ci

AB_METRICS = ("psnr", "ssim", "mse", "flip_ldr")


@dataclass
class ABResult:
    a: str
    b: str
    per_scene: dict = field(default_factory=dict)   # scene -> metric -> {mean, ci, n}
    overall: dict = field(default_factory=dict)     # metric -> {mean, ci, n}
    ms: dict = field(default_factory=dict)          # {"a": ms, "b": ms, "diff": ms}
    recomputed: dict = field(default_factory=dict)  # what this call computed (the rest was cached)

    def worse_by(self, metric: str) -> float:
        """How much worse B is than A on average (positive = worse), in the metric's units."""
        d = self.overall[metric]["mean"]
        if d is None:
            return math.nan
        return -d if HIGHER_IS_BETTER.get(metric, False) else d

    def as_dict(self) -> dict:
        return {"a": self.a, "b": self.b, "per_scene": self.per_scene, "overall": self.overall, "ms": self.ms,
                "recomputed": self.recomputed}

    def recomputed_line(self) -> str:
        r = self.recomputed
        return (f"recomputed: {r.get('runs_computed', 0)} runs ({r.get('runs_cached', 0)} cached), "
                f"{r.get('metrics_computed', 0)} metric sets, {r.get('references_rendered', 0)} references rendered")


def _summary(diffs: list[float]) -> dict:
    arr = np.array([d for d in diffs if math.isfinite(d)], np.float64)
    if len(arr) == 0:
        return {"mean": None, "ci": None, "n": 0}
    ci = bootstrap_ci(arr)
    return {"mean": float(arr.mean()), "ci": list(ci) if ci else None, "n": int(len(arr))}


def compare(a: TechniqueConfig, b: TechniqueConfig, scenes, profile: str = "quick", progress: bool = True,
            study: Study | None = None) -> ABResult:
    """`scenes`: scene specs (built-in names or scene files)."""
    import dataclasses
    if a.label == b.label:
        b = TechniqueConfig(b.label + " (B)", b.name, b.overrides)
    study = study or Study(profile, progress=progress)
    warm = tuple(p for p in study.profile.ghosting if p.warmup) or study.profile.ghosting
    study.profile = dataclasses.replace(study.profile, ghosting=warm)
    out = study.run(list(scenes), [a, b], agreement=False)
    res = ABResult(a.label, b.label, recomputed={k: v for k, v in out.stats.items() if k != "tasks"})
    overall = {m: [] for m in AB_METRICS}
    per_scene: dict = {}
    tests = list(out.views.values())[-1] + [g for gs in out.ghosts.values() for g in gs]
    for r in tests:
        per = per_scene.setdefault(r.scene, {m: [] for m in AB_METRICS})
        for t in r.frames:
            for m in AB_METRICS:
                va, vb = r.per_frame[a.label][t][m], r.per_frame[b.label][t][m]
                if va is not None and vb is not None and math.isfinite(va) and math.isfinite(vb):
                    per[m].append(vb - va)
    for scene, per in per_scene.items():
        res.per_scene[scene] = {m: _summary(v) for m, v in per.items()}
        for m in AB_METRICS:
            overall[m] += per[m]
    res.overall = {m: _summary(v) for m, v in overall.items()}
    statics = list(out.views.values())[-1]
    ma = float(np.median([r.ms[a.label] for r in statics]))
    mb = float(np.median([r.ms[b.label] for r in statics]))
    res.ms = {"a": ma, "b": mb, "diff": mb - ma}
    return res

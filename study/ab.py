"""Scripted A/B comparison of two technique configurations (the study's make-style runs).

Pairs are frames: the static test's kept frame and every ghosting frame of every scene. For each
metric we report the mean paired difference B - A with a 95 % bootstrap confidence interval
(2000 resamples, fixed seed, so the same runs print the same figures), per scene and overall, and
the difference in milliseconds per frame. `gate` says whether B is worse than A beyond a threshold.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .config import TechniqueConfig
from .metrics import HIGHER_IS_BETTER
from .run import Study, is_animated

AB_METRICS = ("psnr", "ssim", "mse", "flip_ldr")


def bootstrap_ci(diffs: np.ndarray, n: int = 2000, seed: int = 0) -> tuple[float, float]:
    if len(diffs) < 2:
        return (math.nan, math.nan)
    rng = np.random.default_rng(seed)
    means = diffs[rng.integers(0, len(diffs), (n, len(diffs)))].mean(axis=1)
    return float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))


@dataclass
class ABResult:
    a: str
    b: str
    per_scene: dict = field(default_factory=dict)   # scene -> metric -> {mean, ci, n}
    overall: dict = field(default_factory=dict)     # metric -> {mean, ci, n}
    ms: dict = field(default_factory=dict)          # {"a": ms, "b": ms, "diff": ms}

    def worse_by(self, metric: str) -> float:
        """How much worse B is than A on average (positive = worse), in the metric's units."""
        d = self.overall[metric]["mean"]
        return -d if HIGHER_IS_BETTER.get(metric, False) else d

    def as_dict(self) -> dict:
        return {"a": self.a, "b": self.b, "per_scene": self.per_scene, "overall": self.overall, "ms": self.ms}


def _summary(diffs: list[float]) -> dict:
    arr = np.array([d for d in diffs if math.isfinite(d)], np.float64)
    if len(arr) == 0:
        return {"mean": math.nan, "ci": [math.nan, math.nan], "n": 0}
    return {"mean": float(arr.mean()), "ci": list(bootstrap_ci(arr)), "n": int(len(arr))}


def compare(a: TechniqueConfig, b: TechniqueConfig, scenes, profile: str = "quick", progress: bool = True,
            study: Study | None = None) -> ABResult:
    if a.label == b.label:
        b = TechniqueConfig(b.label + " (B)", b.name, b.overrides)
    study = study or Study(profile, progress=progress)
    res = ABResult(a.label, b.label)
    overall = {m: [] for m in AB_METRICS}
    ms_a, ms_b = [], []
    for scene in scenes:
        tests = ["static"] + (["ghosting"] if is_animated(scene) else [])
        per = {m: [] for m in AB_METRICS}
        for test in tests:
            r = study.run_test(scene, test, [a, b])
            for t in r.frames:
                for m in AB_METRICS:
                    va, vb = r.per_frame[a.label][t][m], r.per_frame[b.label][t][m]
                    if va is not None and vb is not None and math.isfinite(va) and math.isfinite(vb):
                        per[m].append(vb - va)
            ms_a.append(r.ms[a.label])
            ms_b.append(r.ms[b.label])
        res.per_scene[scene.name] = {m: _summary(v) for m, v in per.items()}
        for m in AB_METRICS:
            overall[m] += per[m]
    res.overall = {m: _summary(v) for m, v in overall.items()}
    ma, mb = float(np.median(ms_a)), float(np.median(ms_b))
    res.ms = {"a": ma, "b": mb, "diff": mb - ma}
    return res

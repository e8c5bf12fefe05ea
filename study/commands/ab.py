"""Scripted A/B comparison of two technique configurations (the study's make-style runs).

Pairs are frames of the converged protocols: the static test's frame after its full history and
every frame of the warm ghosting test, of every scene. For each metric we report the mean paired
difference B - A with a 95 % bootstrap confidence interval (2000 resamples, fixed seed, so the same
runs print the same figures), per scene and overall, and the difference in cost per frame. With a
single pair there is no bootstrap interval: it is reported as None (null in JSON) with n = 1, except
for the JOD of ColorVideoVDP (study.metrics.video; one figure per ghosting video), whose single pair
carries the interval of the two figures' reference uncertainties (each about 2 sd), added in
quadrature ("interval": "reference"). `worse_by` says how much worse B is than A.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from study.config.techniques import TechniqueConfig
from study.engine.runner import Study
from study.metrics.suite import HIGHER_IS_BETTER
from study.reporting.intervals import bootstrap_ci

AB_METRICS = ("psnr", "ssim", "mse", "flip_ldr", "jod")


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
                f"{r.get('metrics_computed', 0)} metric sets, {r.get('video_computed', 0)} video metric sets, "
                f"{r.get('references_rendered', 0)} references rendered")


def _summary(diffs: list[float], us: list | None = None) -> dict:
    """`us`: each pair's reference uncertainty, for the interval of a single pair."""
    keep = [i for i, d in enumerate(diffs) if math.isfinite(d)]
    arr = np.array([diffs[i] for i in keep], np.float64)
    if len(arr) == 0:
        return {"mean": None, "ci": None, "n": 0}
    if len(arr) == 1 and us and us[keep[0]] is not None:
        u = us[keep[0]]
        return {"mean": float(arr[0]), "ci": [float(arr[0] - u), float(arr[0] + u)], "n": 1, "interval": "reference"}
    ci = bootstrap_ci(arr)
    return {"mean": float(arr.mean()), "ci": list(ci) if ci else None, "n": int(len(arr)),
            "interval": "bootstrap" if ci else None}


def compare(a: TechniqueConfig, b: TechniqueConfig, scenes, profile: str = "quick", progress: bool = True,
            study: Study | None = None, video: bool = True) -> ABResult:
    """`scenes`: scene specs (built-in names or scene files). `video`: judge A and B by the video
    metric wherever the study's [video] judges a scene (False: not at all, the quicker loop)."""
    import dataclasses
    if a.label == b.label:
        b = TechniqueConfig(b.label + " (B)", b.name, b.overrides)
    study = study or Study(profile, progress=progress)
    warm = tuple(p for p in study.profile.ghosting if p.warmup) or study.profile.ghosting
    vid = dataclasses.replace(study.profile.video, techniques=()) if video else \
        dataclasses.replace(study.profile.video, metric="none")
    study.profile = dataclasses.replace(study.profile, ghosting=warm, video=vid)
    # each test at the bound the study settled it at: A's figures there are cached, B's judged once
    out = study.run(list(scenes), [a, b], agreement=False, seeded=True)
    res = ABResult(a.label, b.label, recomputed={k: v for k, v in out.stats.items()
                                                   if k not in ("tasks", "task_seconds", "task_seconds_by_scene")})
    overall = {m: [] for m in AB_METRICS}
    overall_u = {m: [] for m in AB_METRICS}
    per_scene: dict = {}
    per_u: dict = {}
    tests = list(out.views.values())[-1] + [g for gs in out.ghosts.values() for g in gs]

    def pair(per, pu, m, va, vb, ua=None, ub=None):
        if va is not None and vb is not None and math.isfinite(va) and math.isfinite(vb):
            per[m].append(vb - va)
            pu[m].append(math.hypot(ua, ub) if ua is not None and ub is not None else None)
    for r in tests:
        per = per_scene.setdefault(r.scene, {m: [] for m in AB_METRICS})
        pu = per_u.setdefault(r.scene, {m: [] for m in AB_METRICS})
        for t in r.frames:
            for m in AB_METRICS:
                # only the JOD's single pair takes its interval from the reference uncertainty
                ua, ub = ((r.uncertainty.get(x, {}).get(t, {}).get(m) for x in (a.label, b.label)) if m == "jod"
                          else (None, None))
                pair(per, pu, m, r.per_frame[a.label][t].get(m), r.per_frame[b.label][t].get(m), ua, ub)
        if r.kind == "ghosting" and a.label in r.jod and b.label in r.jod:    # one JOD per video
            pair(per, pu, "jod", r.jod[a.label].get("sequence"), r.jod[b.label].get("sequence"),
                 r.jod_u[a.label].get("sequence"), r.jod_u[b.label].get("sequence"))
    for scene, per in per_scene.items():
        res.per_scene[scene] = {m: _summary(v, per_u[scene][m] if m == "jod" else None) for m, v in per.items()}
        for m in AB_METRICS:
            overall[m] += per[m]
            overall_u[m] += per_u[scene][m]
    res.overall = {m: _summary(v, overall_u[m] if m == "jod" else None) for m, v in overall.items()}
    statics = list(out.views.values())[-1]
    ma = float(np.median([r.ms[a.label] for r in statics]))
    mb = float(np.median([r.ms[b.label] for r in statics]))
    res.ms = {"a": ma, "b": mb, "diff": mb - ma}
    return res

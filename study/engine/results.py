"""A study's results as the reporting reads them: per test its metrics, costs and artefact keys
(TestResult), the whole study's (StudyResults), and the pixels behind them (Artefacts: a run's
judged frames and a metrics record's maps, each verified against its done record as it is read).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from study.config.defaults import THESIS_HISTORY
from study.engine.plan import shown_frames  # noqa: F401  (the frames the report's sliders show)


@dataclass
class TestResult:
    scene: str
    test: str                                  # protocol label
    frames: list[int]
    per_frame: dict[str, dict[int, dict]]      # label -> frame id -> metrics
    ms: dict[str, float]                       # label -> total cost per output frame (study.engine.costs)
    temporal: dict[str, float] = field(default_factory=dict)
    recomputed: list[str] = field(default_factory=list)
    artefacts: dict[str, dict] = field(default_factory=dict)   # label -> folder, keys, output space, frame file
    stats: dict[str, dict] = field(default_factory=dict)       # label -> frame id -> counters (sparse SS)
    reference_keys: dict[int, str] = field(default_factory=dict)
    costs: dict[str, dict] = field(default_factory=dict)       # label -> study.engine.costs figures
    width: int = 0
    height: int = 0
    kind: str = "static"
    checkpoints: dict[str, dict[int, dict]] = field(default_factory=dict)   # static: label -> n -> metrics
    # label -> frame id -> metric -> the reference's share of the figure's uncertainty
    # (study.metrics.uncertainty); the figures in per_frame have the reference's bias removed
    uncertainty: dict[str, dict[int, dict]] = field(default_factory=dict)
    temporal_u: dict[str, float] = field(default_factory=dict)
    reference_bound_lsb: float = 0.0           # the per-pixel bound its references were refined to
    reference_bounds_lsb: dict = field(default_factory=dict)   # scene time -> its reference's, where instants differ
    # ColorVideoVDP (study.metrics.video): label -> {'sequence' (a ghosting test) or a static view's
    # frame id as a string -> JOD}, bias removed, and its uncertainty
    jod: dict[str, dict] = field(default_factory=dict)
    jod_u: dict[str, dict] = field(default_factory=dict)
    video: dict = field(default_factory=dict)  # the video metric's settings: metric, display, fps


@dataclass
class StudyResults:
    statics: list = field(default_factory=list)        # one TestResult per scene (all checkpoints)
    views: dict = field(default_factory=dict)          # static view label -> [TestResult]
    ghosts: dict = field(default_factory=dict)         # ghosting protocol name -> [TestResult]
    sweeps: list = field(default_factory=list)
    sharpen_sweeps: list = field(default_factory=list)   # TestResults: both thesis TAAs per sharpen strength
    agreements: dict = field(default_factory=dict)     # scene -> agreement dict
    references: dict = field(default_factory=dict)     # scene -> Reference (frame 0)
    stats: dict = field(default_factory=dict)
    artefacts: "Artefacts | None" = None                # the pixels behind the figures
    reference: object = None                           # (scene name, t, w, h[, protocol]) -> Reference
    display: object = None                             # (scene name, t, w, h) -> its DisplayTransform
    thesis_history: int = THESIS_HISTORY
    # scene -> {"bound_lsb": its references' final per-pixel bound, "over": [figures still over their
    # tolerance there], "rounds": bounds tried} (study.engine.precision)
    precision: dict = field(default_factory=dict)
    tolerances: dict = field(default_factory=dict)



class Artefacts:
    """Read-only access to the frames and maps of a study's artefacts, verified on read."""

    def __init__(self, cache_root):
        from study.engine.store import Store
        self.store = Store(Path(cache_root))

    def frame(self, a: dict, f: int) -> np.ndarray:
        """Frame f of the run `a` (a TestResult.artefacts entry), RGB."""
        folder = Path(a["folder"])
        rec = self.store.done(folder, a["run_key"])
        if rec is None:
            raise RuntimeError(f"run {folder} is not complete")
        ch = self.store.read_image(folder, f"frame_{f:04d}.exr", rec)
        return np.stack([ch[c] for c in "RGB"], -1)

    def maps(self, a: dict, f: int) -> dict:
        """The SSIM/FLIP maps of frame f of the metrics record of `a`."""
        folder = Path(a["metrics_folder"])
        rec = self.store.done(folder, a["metrics_key"])
        if rec is None:
            raise RuntimeError(f"metrics {folder} are not complete")
        return self.store.read_image(folder, f"maps_{f:04d}.exr", rec)


    def video_map(self, a: dict, f: int):
        """ColorVideoVDP's difference map of frame f (the last of a video, or a static view's) of
        the video record of `a`, or None when that frame has none."""
        folder = Path(a["video_folder"])
        rec = self.store.done(folder, a["video_key"])
        if rec is None:
            raise RuntimeError(f"video metrics {folder} are not complete")
        name = f"maps_{f:04d}.exr"
        return self.store.read_image(folder, name, rec)["cvvdp"] if name in rec["files"] else None


def view(full: TestResult, label: str, n: int) -> TestResult:
    """The static test as one protocol reads it: history length n (the checkpoint n for techniques
    with history, the single judged frame for those without)."""
    v = TestResult(full.scene, label, [n], {}, dict(full.ms), temporal=dict(full.temporal),
                   stats={}, reference_keys=full.reference_keys, costs=full.costs, width=full.width,
                   height=full.height, kind="static", temporal_u=dict(full.temporal_u),
                   reference_bound_lsb=full.reference_bound_lsb, reference_bounds_lsb=dict(full.reference_bounds_lsb),
                   video=dict(full.video))
    for l, per in full.per_frame.items():
        f = n if n in per else max(per)
        v.per_frame[l] = {n: per[f]}
        v.uncertainty[l] = {n: full.uncertainty.get(l, {}).get(f, {})}
        if str(f) in full.jod.get(l, {}):        # the view's image pair judged by ColorVideoVDP
            v.per_frame[l] = {n: {**per[f], "jod": full.jod[l][str(f)]}}
            v.uncertainty[l] = {n: {**v.uncertainty[l][n], "jod": full.jod_u[l][str(f)]}}
        v.artefacts[l] = {**full.artefacts[l], "frame": f}
        if l in full.stats and f in full.stats[l]:
            v.stats[l] = {n: full.stats[l][f]}
    return v



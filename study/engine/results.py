"""A study's results as the reporting reads them: per test its metrics, costs and artefact keys
(TestResult), the whole study's (StudyResults), and the pixels behind them (Artefacts: a run's
judged frames and a metrics record's maps, each verified against its done record as it is read).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from references.settings import SE_BOUND_LSB

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

    def frame_8bit(self, a: dict, f: int, disp) -> np.ndarray:
        """Frame f of the run `a` as the 8-bit display image it was judged as under `disp` (a
        display.DisplayTransform): the one its metrics task kept (a run pruned once judged keeps no
        float frame: study.engine.judge), else its float frame through `disp`."""
        folder, name = Path(a["metrics_folder"]), f"shown_{f:04d}.png"
        rec = self.store.done(folder, a["metrics_key"])
        if rec is None or name not in rec["files"]:
            return disp.output(self.frame(a, f), a["output_space"])[2]
        from PIL import Image
        self.store.verify(folder / name, rec)
        with Image.open(folder / name) as im:
            return np.asarray(im.convert("RGB"))

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


def with_drift(res: TestResult, drifts: dict) -> TestResult:
    """A figure's stated uncertainty: its halves' plus its change from the coarser bound (`drifts`:
    test -> figure -> drift, study.engine.precision.decide)."""
    change = drifts.get((res.scene, res.test), {})
    if not change:
        return res
    res.uncertainty = {label: {f: {m: u + change.get((res.test, label, f, m), 0.0) if u is not None else None
                                   for m, u in us.items()} for f, us in per.items()}
                       for label, per in res.uncertainty.items()}
    res.temporal_u = {label: u + change.get((res.test, label, None, "temporal"), 0.0) if u is not None else None
                      for label, u in res.temporal_u.items()}
    return res


def run_records(root: Path, test) -> dict:
    """label -> the done record of each run of a planned test (None where it is not complete)."""
    from study.engine.store import Store
    store = Store(root)
    return {c.label: store.done(Path(test.run_folders[c.label]), test.run_keys[c.label]) for c in test.configs}


def test_result(root: Path, test, results: dict, costs: dict) -> TestResult:
    """A planned test's TestResult from the tasks' results (key -> result), its runs' records and
    the measured costs ((scene, label) -> cost)."""
    recs = run_records(root, test)
    res = TestResult(test.scene, test.protocol.name, [], {}, {}, width=test.width, height=test.height,
                     kind=test.protocol.kind, reference_bound_lsb=test.ref_settings.get("se_bound_lsb", SE_BOUND_LSB),
                     reference_bounds_lsb={t: s.get("se_bound_lsb", SE_BOUND_LSB) for t, s in test.ref_settings_at.items()},
                     reference_keys={t: k for t, k in test.reference_tasks.items()})
    frames = set()
    for c in test.configs:
        m = results[test.metrics_keys[c.label]]
        if m["computed"]:
            res.recomputed.append(c.label)
        per = {int(f): v for f, v in m["data"]["per_frame"].items()}
        res.per_frame[c.label] = per
        res.uncertainty[c.label] = {int(f): v for f, v in m["data"]["uncertainty"].items()}
        res.temporal_u[c.label] = m["data"].get("temporal_u")
        frames |= set(per)
        t = m["data"].get("temporal")
        res.temporal[c.label] = math.nan if t is None else t
        rec = recs[c.label] or {}
        if rec.get("stats"):
            res.stats[c.label] = {int(f): v for f, v in rec["stats"].items()}
        cost = costs.get((test.scene, c.label), {})
        res.costs[c.label] = cost
        res.ms[c.label] = cost.get("total_ms", math.nan)
        res.artefacts[c.label] = {"folder": test.run_folders[c.label], "run_key": test.run_keys[c.label],
                                  "metrics_key": test.metrics_keys[c.label],
                                  "metrics_folder": test.metrics_folders[c.label],
                                  "output_space": (rec or {}).get("output_space", "linear"),
                                  "technique": c.name, "overrides": list(c.overrides),
                                  "maps_for": test.maps_for[c.label]}
    for label, vkey in test.video_keys.items():
        if vkey in results:
            res.jod[label] = {k: v for k, v in results[vkey]["data"]["jod"].items()}
            res.jod_u[label] = dict(results[vkey]["data"]["jod_u"])
            res.video = {k: results[vkey]["data"][k] for k in ("metric", "display", "fps")}
            res.artefacts[label]["video_key"] = vkey
            res.artefacts[label]["video_folder"] = str(Path(root) / "video" / test.scene / vkey)
    res.frames = sorted(frames)
    if test.protocol.kind == "static":
        res.checkpoints = res.per_frame
    return res

"""Planning: what a study computes, as a graph of pure, content-keyed tasks.

A study is a list of tests (scene, protocol, techniques). For each the planner keys
  reference   (scene, frame)                    -- study.engine.reference_task
  run         (scene, protocol, the techniques that share its raster frames) -- study.engine.run_task
  metrics     (one technique's run; a test's are judged by one task) -- study.engine.judge
  agreement   (scene)                           -- study.engine.agreement
  video       (one technique's run, ColorVideoVDP; a test's by one task, in the study's last round)
                                                -- study.engine.video_task
from the keys of their inputs (provenance.task_key), and leaves out every task whose artefact is
already complete in the cache. Each planned Task carries its inputs as a frozen spec of its kind
(study.engine.specs), read by name. Where the tasks run is study.engine.execute's business; the tables
and figures made from their results are study.reporting's.
"""
from __future__ import annotations

import secrets
from dataclasses import dataclass, field
from pathlib import Path

from provenance import Normalized, task_key

from study.config.protocols import Protocol, judged_steps
from study.config.techniques import TechniqueConfig
from study.engine import tasks as T
from study.engine.reuse_chain import bridge_by_kept, chain_reuse
from study.engine.specs import AgreementSpec, MetricsSpec, ReferenceSpec, RunSpec, Task, VideoSpec


# The code each task kind's key names (with, for a run, the technique's class): provenance hashes
# these modules and every own module they use.
CODE = {
    "reference": ("references.cache", "references.render", "display"),
    "run": ("study.engine.drive", "study.engine.run_task"),
    "metrics": ("study.engine.judge", "study.metrics.suite", "display"),
    "agreement": ("study.engine.agreement",),
    "video": ("study.engine.video_task", "study.metrics.video", "study.metrics.uncertainty", "display"),
}


@dataclass
class Test:
    """One (scene, protocol, techniques) and the keys of everything it reads."""
    scene: str                    # scene name
    spec: str                     # what load_scene takes (built-in name or file path)
    protocol: Protocol
    configs: list
    width: int
    height: int
    frame_times: dict = field(default_factory=dict)     # label -> {frame id: scene time}
    run_keys: dict = field(default_factory=dict)        # label -> key
    run_folders: dict = field(default_factory=dict)
    metrics_keys: dict = field(default_factory=dict)
    metrics_folders: dict = field(default_factory=dict)
    reference_tasks: dict = field(default_factory=dict)  # scene time -> reference task key
    maps_for: dict = field(default_factory=dict)        # label -> frame ids whose maps are kept
    keep: dict = field(default_factory=dict)            # label -> frame ids kept once judged (None: all)
    ref_settings: dict = field(default_factory=dict)    # its references' settings
    ref_settings_at: dict = field(default_factory=dict)  # scene time -> those of its reference there
    video_keys: dict = field(default_factory=dict)      # label -> key of its JOD record (study.metrics.video)


@dataclass
class Plan:
    tasks: dict = field(default_factory=dict)           # key -> Task (only what must be computed)
    tests: list = field(default_factory=list)
    agreements: dict = field(default_factory=dict)      # scene name -> (key, path)
    cached: dict = field(default_factory=dict)          # key -> result of a complete artefact

    def counts(self, cached: bool = True) -> dict:
        """Planned tasks by kind; `cached` False: but those whose file is already in the cache
        (Task.likely_cached: a reference, whose task reads it)."""
        out: dict = {}
        for t in self.tasks.values():
            if cached or not t.likely_cached:
                out[t.kind] = out.get(t.kind, 0) + 1
        return out

    def to_compute(self) -> dict:
        """Planned tasks by kind but those already in the cache."""
        return self.counts(cached=False)

    def complete(self) -> int:
        """Artefacts already made: the cached results and the references found in the cache."""
        return len(self.cached) + sum(t.likely_cached for t in self.tasks.values())


SHOWN_FRAMES = 24


def shown_frames(frames: list, n: int = SHOWN_FRAMES) -> list:
    """The frames of a sequence the report shows (its frame slider): at most n, evenly spaced."""
    if len(frames) <= n:
        return list(frames)
    import numpy as np
    idx = np.linspace(0, len(frames) - 1, n).round().astype(int)
    return [frames[i] for i in sorted(set(idx))]


def run_steps(schedule: list, inp) -> list:
    """What a run's output depends on of its schedule, for its key. A technique with history sees
    every step; one without sees only the instants it is judged at (and, through motion vectors or
    cameras, the instant before), so a warm-up it never runs leaves its key alone."""
    if inp.sampling == "sequence":
        return [(s.t, s.k, s.keep, s.reset, s.prev_t, s.frame) for s in schedule]
    moves = inp.cameras or bool({"motion", "prev_depth"} & set(inp.buffers))
    return [(s.t, s.prev_t if moves else None, s.frame) for s in judged_steps(schedule, inp.sampling)]


_STEPS: dict = {}


def _normalized_steps(scene, protocol: Protocol, schedule: list, inp, seen: tuple) -> Normalized:
    """A run's step list, normalised for its key once per process: every precision round plans
    the same tests again (a no-op study plans twice), and normalising a 256-step list is most of
    what keying a run costs."""
    memo = (scene.content_hash, protocol, seen)
    if memo not in _STEPS:
        _STEPS[memo] = Normalized(run_steps(schedule, inp))
    return _STEPS[memo]


class Planner:
    def __init__(self, ctx: T.Context, ref_settings: dict, agreement_samples: int | None,
                 ref_settings_of: dict | None = None, display_settings: dict | None = None, video=None,
                 video_final: bool | frozenset = False, prune: bool | frozenset = True):
        """`ref_settings_of`: (scene name, protocol name) -> the references' settings of that test
        where they differ from `ref_settings` (the precision its figures need; study.engine.precision).
        `display_settings`: the references every frame's display transform comes from
        (study.engine.tasks.display_of), `ref_settings` if not given. `video`: the video metric's
        settings (study.config.video.Video); its tasks are planned only with `video_final` (a
        study's last round; or the tests, (scene, protocol), settled already), but in every round
        the runs it will read keep every judged frame.
        `prune`: a metrics task prunes its runs to their kept frames once judged; without, the runs
        stay whole for a later round's references (the runner prunes a test's runs once it settles:
        study.engine.prune); or the tests ((scene, protocol)) whose runs are pruned (study.engine.disk)."""
        from study.engine.store import Store
        self.ctx, self.ref_settings, self.agreement_samples = ctx, dict(ref_settings), agreement_samples
        self.ref_settings_of = dict(ref_settings_of or {})
        self.display_settings = dict(display_settings or ref_settings)
        from study.config.video import Video
        self.video = video if video is not None else Video(metric="none")
        self.video_final, self.prune = video_final, prune
        self.store = Store(Path(ctx.cache_root))
        self.plan = Plan()
        self._run_task_of: dict = {}     # run key -> key of the run task that makes it
        self._judge_of, self._ref_keys, self._mark = {}, {}, secrets.token_hex(8)   # run key -> what its task judges
        self._feeds_of: dict = {}        # run key -> [(metrics folder, key)] the planned run is judged into
        self._metrics_task_of: dict = {}  # metrics key -> key of the metrics task that judges it

    def is_final(self, test: tuple) -> bool:
        """Whether a test's ((scene, protocol)) references are final (`video_final`): its video
        metric's and agreement's tasks are planned."""
        return test in self.video_final if isinstance(self.video_final, frozenset) else bool(self.video_final)

    def settings(self, scene, protocol: str, t: int | None = None) -> dict:
        """A test's references' settings; at instant t, that instant's own where it has one."""
        got = self.ref_settings_of.get((scene.name, protocol, t)) if t is not None else None
        return dict(got or self.ref_settings_of.get((scene.name, protocol), self.ref_settings))

    # -- keys ----------------------------------------------------------------------------------------
    def reference_key(self, scene, t: int, w: int, h: int, settings: dict) -> str:
        memo = (scene.content_hash, t, w, h, repr(sorted(settings.items())))
        if memo not in self._ref_keys:     # each test asks again for the frames it shares with others
            self._ref_keys[memo] = task_key("reference", {"scene": scene.content_hash, "t": t, "res": (w, h),
                                                          "camera": scene.camera(t, w, h).to_world.round(12).tolist(),
                                                          "settings": settings},
                                            code=CODE["reference"])
        return self._ref_keys[memo]

    def _reference(self, spec: str, scene, t: int, w: int, h: int, settings: dict) -> str:
        key = self.reference_key(scene, t, w, h, settings)
        if key not in self.plan.tasks:
            from references import ReferenceCache
            from references.cache import reuses
            # a reference that keeps the previous frame's pixels (references.reuse) runs after it
            deps = (self._reference(spec, scene, t - 1, w, h, settings),) if reuses(
                scene, t, w, h, settings.get("reuse", False), settings.get("reuse_since", 0)) else ()
            self.plan.tasks[key] = Task(key, ReferenceSpec(self.ctx, spec, t, w, h, dict(settings)), deps,
                                        likely_cached=ReferenceCache(self.store.root).has(scene, t, w, h, **settings))
        return key

    def _refs(self, spec: str, scene, w: int, h: int, judged, shown=()) -> tuple:
        """The reference tasks of `judged` ((t, settings) pairs) and of the display references of the
        instants `shown` (`display_settings`), in order, once each; a display reference needs none
        where its display record is filed and nothing judges against it (references.cache)."""
        from references import ReferenceCache
        out = [self._reference(spec, scene, t, w, h, s) for t, s in judged]
        for t in shown:
            key = self.reference_key(scene, t, w, h, self.display_settings)
            if key in out or key in self.plan.tasks or not ReferenceCache(self.store.root).has_display(
                    scene, t, w, h, **self.display_settings):
                out.append(self._reference(spec, scene, t, w, h, self.display_settings))
        return tuple(dict.fromkeys(out))

    # -- tests -----------------------------------------------------------------------------------------
    def add_test(self, spec: str, scene, protocol: Protocol, configs: list[TechniqueConfig],
                 w: int, h: int, maps="last", keep="all") -> Test:
        """Plan one test. `maps`: which judged frames keep their SSIM/FLIP maps: 'last' (the last
        judged frame of each run), 'none', or a tuple of history lengths (the static views; a
        technique without history keeps its one frame). `keep`: which of a run's frames stay in
        the cache once judged: 'all', 'maps' (those with maps), 'shown' (shown_frames) or 'none'.
        At 1600x900 a frame is ~9 MB and the full profile judges ~9000: the rest are dropped, and
        a run is re-made if its metrics are ever needed again."""
        if keep not in ("all", "maps", "shown", "none"):
            raise ValueError(f"keep must be 'all', 'maps', 'shown' or 'none', not {keep!r}")
        schedule = protocol.schedule(scene)
        settings = self.settings(scene, protocol.name)
        test = Test(scene.name, spec, protocol, list(configs), w, h, ref_settings=settings)
        kept_t = sorted({s.t for s in schedule if s.keep})
        at = test.ref_settings_at = chain_reuse({t: self.settings(scene, protocol.name, t) for t in kept_t},
                                                (self.display_settings, settings), bridge_by_kept(scene, w, h))
        ref_keys = {t: self.reference_key(scene, t, w, h, at[t]) for t in kept_t}
        disp_keys = {t: self.reference_key(scene, t, w, h, self.display_settings) for t in kept_t}
        missing, steps = [], {}
        # the columns the video metric judges here; in a ghosting test (in any round) their runs
        # keep every judged frame, the video's
        vlabels = {c.label for c in configs if self.video.judges(protocol.kind, scene.name, c, protocol.name)}
        whole = vlabels if protocol.kind == "ghosting" else set()
        for c in configs:
            inp = c.inputs()
            seen = (inp.sampling, inp.cameras, tuple(sorted(inp.buffers)))
            if seen not in steps:       # the techniques of a test share a few step lists
                steps[seen] = _normalized_steps(scene, protocol, schedule, inp, seen)
            judged = judged_steps(schedule, inp.sampling)
            test.frame_times[c.label] = {s.frame: s.t for s in judged}
            # Display-space techniques see a display transform built from a reference.
            inputs = [disp_keys[t] for t in kept_t] if inp.display else []
            key = task_key("run", {"scene": scene.content_hash, "res": (w, h), "schedule": steps[seen],
                                   "technique": c.key_data()}, inputs, code=[c.code(), *CODE["run"]])
            folder = self.store.folder(protocol.kind, scene.name, key)
            test.run_keys[c.label], test.run_folders[c.label] = key, str(folder)
            frames = sorted(test.frame_times[c.label])
            if maps == "none":
                mf = []
            elif isinstance(maps, tuple):
                mf = sorted({max(f for f in frames if f <= v) for v in maps if any(f <= v for f in frames)}
                            | {frames[-1]})
            else:
                mf = [frames[-1]]
            test.maps_for[c.label] = mf
            test.keep[c.label] = {"all": None, "maps": mf, "shown": shown_frames(frames), "none": []}[keep]
            if c.label in whole:
                test.keep[c.label] = None
            ts = sorted(set(test.frame_times[c.label].values()))
            if ("frames", inp.sampling) not in steps:   # the judged frames depend on the sampling alone
                steps[("frames", inp.sampling)] = Normalized(test.frame_times[c.label])
            mkey = task_key("metrics", {"frames": steps[("frames", inp.sampling)], "maps": mf,
                                        **({} if protocol.hdr else {"hdr": False})},
                            [key] + [ref_keys[t] for t in ts] + [disp_keys[t] for t in ts], code=CODE["metrics"])
            mfolder = self.store.root / "metrics" / scene.name / mkey
            test.metrics_keys[c.label], test.metrics_folders[c.label] = mkey, str(mfolder)
            mrec = self._complete(mfolder, mkey, verify_files=bool(mf))
            if mrec is not None and self._run_intact(folder, key, verify=bool(mf)) and (
                    c.label not in whole or self.store.done(folder, key, whole=True)):
                self.plan.cached[mkey] = {"kind": "metrics", "key": mkey, "data": mrec["data"], "computed": False}
                continue
            missing.append(c)
        test.reference_tasks = ref_keys
        if missing:
            # The metrics task reads every frame of its run: a run with a damaged file is re-made.
            need_run = [c for c in missing if self._complete(Path(test.run_folders[c.label]), test.run_keys[c.label],
                                                             verify_files=True, whole=True) is None]
            # a run another test already plans (a technique without history judged at the same
            # instants, e.g. under the cold and the warm ghosting protocol) is made once
            shared = {c.label: self._run_task_of[test.run_keys[c.label]] for c in need_run
                      if test.run_keys[c.label] in self._run_task_of}
            need_run = [c for c in need_run if c.label not in shared]
            # a run pruned once judged is judged as it is made (study.engine.run_task): no float frame on disk
            streams = [c for c in missing if self.prunes(test) and test.keep[c.label] is not None and c.label not in vlabels
                       and test.metrics_keys[c.label] not in self._metrics_task_of and (
                           c in need_run or self._judge_of.get(test.run_keys[c.label]) is not None)]
            for c in missing:     # the metrics each planned run feeds (run_task skips a run judged meanwhile)
                if test.run_keys[c.label] in self._feeds_of:
                    self._feeds_of[test.run_keys[c.label]].append((test.metrics_folders[c.label], test.metrics_keys[c.label]))
            run_dep = ()
            if need_run:
                rdeps = self._refs(spec, scene, w, h, (), kept_t) \
                    if any(c.inputs().display for c in need_run) else ()
                rkey = task_key("runs", sorted(test.run_keys[c.label] for c in need_run),     # and what it judges
                                sorted(test.metrics_keys[c.label] for c in streams if c in need_run))
                feeds = {c.label: [(test.metrics_folders[c.label], test.metrics_keys[c.label])] for c in need_run}
                self._feeds_of.update({test.run_keys[c.label]: feeds[c.label] for c in need_run})
                judge: list = []
                self.plan.tasks[rkey] = Task(rkey, RunSpec(
                    self.ctx, spec, w, h, protocol, need_run, {c.label: test.run_keys[c.label] for c in need_run},
                    {c.label: test.run_folders[c.label] for c in need_run}, self.display_settings, feeds, judge), rdeps)
                run_dep = (rkey,)
                self._run_task_of.update({test.run_keys[c.label]: rkey for c in need_run})
                self._judge_of.update({test.run_keys[c.label]: judge for c in need_run})
            by_task: dict = {}
            for c in streams:         # a group per test and run task: its items, their references
                by_task.setdefault(self._run_task_of[test.run_keys[c.label]], []).append(c)
            for rk, cs in by_task.items():
                ts = sorted({t for c in cs for t in test.frame_times[c.label].values()})
                self._judge_of[test.run_keys[cs[0].label]].append(
                    {"items": [self._item(test, c, vlabels) for c in cs], "ref_settings": {t: at[t] for t in ts}})
                task = self.plan.tasks[rk]
                task.deps = tuple(dict.fromkeys(task.deps + self._refs(spec, scene, w, h, [(t, at[t]) for t in ts], ts)))
            # one metrics task judges the test's missing techniques together (study.engine.judge); a
            # metrics key another test's task already judges (a shared run's) is left to it
            mine = [c for c in missing if test.metrics_keys[c.label] not in self._metrics_task_of]
            if mine:
                ts = sorted({t for c in mine for t in test.frame_times[c.label].values()})
                made_by = {shared.get(c.label) or (run_dep[0] if c in need_run else None) for c in mine} - {None}
                deps = tuple(sorted(made_by)) + self._refs(spec, scene, w, h, [(t, at[t]) for t in ts], ts)
                items = [self._item(test, c, vlabels) for c in mine]
                gkey = task_key("metrics-of", sorted(it["key"] for it in items))
                self.plan.tasks[gkey] = Task(gkey, MetricsSpec(
                    self.ctx, spec, w, h, items, {t: at[t] for t in ts}, self.display_settings), deps)
                self._metrics_task_of.update({it["key"]: gkey for it in items})
        if self.is_final((scene.name, protocol.name)) and vlabels:
            made = {c.label: self._run_task_of.get(test.run_keys[c.label]) for c in configs}
            self._add_video(spec, scene, test, [c for c in configs if c.label in vlabels], at, made,
                            ref_keys, disp_keys)
        self.plan.tests.append(test)
        return test

    def _item(self, test: Test, c, vlabels: set) -> dict:
        """The metrics item of column `c` (study.engine.judge.metrics_task lists its fields)."""
        return {"label": c.label, "run_folder": test.run_folders[c.label], "run_key": test.run_keys[c.label], "mark": self._mark,
                "frame_times": test.frame_times[c.label], "maps_for": test.maps_for[c.label],
                "keep": test.keep[c.label] if self.prunes(test) else None, "hdr": test.protocol.hdr,
                "shown_8bit": c.label not in vlabels, "key": test.metrics_keys[c.label], "folder": test.metrics_folders[c.label]}

    def _add_video(self, spec, scene, test, configs, at, made, ref_keys, disp_keys) -> None:
        """The JOD of each column the video metric judges, once this round's runs are made (`at`:
        scene time -> its reference's settings)."""
        from study.metrics.video import VERSION
        video = self.video
        items = []
        for c in configs:
            ft = test.frame_times[c.label]
            frames = sorted(ft) if test.protocol.kind == "ghosting" else list(test.maps_for[c.label])
            ts = sorted({ft[f] for f in frames})
            vkey = task_key("video", {"frames": {f: ft[f] for f in frames}, "kind": test.protocol.kind,
                                      "video": video.key_data(), "cvvdp": VERSION},
                            [test.run_keys[c.label]] + [ref_keys[t] for t in ts] + [disp_keys[t] for t in ts],
                            code=CODE["video"])
            folder = self.store.root / "video" / scene.name / vkey
            test.video_keys[c.label] = vkey
            rec = self._complete(folder, vkey, verify_files=True)
            if rec is not None:
                self.plan.cached[vkey] = {"kind": "video", "key": vkey, "data": rec["data"], "computed": False}
                continue
            items.append({"label": c.label, "run_folder": test.run_folders[c.label], "run_key": test.run_keys[c.label],
                          "frame_times": ft, "frames": frames, "key": vkey, "folder": str(folder), "ts": ts})
        # a task per column: at ~7 s each (320x180) they fill a round's workers evenly, where one
        # task per test (~50 s) ended a round on one worker while the other waited
        for it in items:
            deps = tuple({made[it["label"]]} - {None}) + self._refs(
                spec, scene, test.width, test.height, [(t, at[t]) for t in it["ts"]], it["ts"])
            gkey = task_key("video-of", [it["key"]])
            self.plan.tasks[gkey] = Task(gkey, VideoSpec(
                self.ctx, spec, test.width, test.height, [it], {t: at[t] for t in it["ts"]},
                self.display_settings, video.task_data(), test.protocol.kind), deps)

    def prunes(self, test: Test) -> bool:
        """Whether the test's metrics task prunes its runs once judged."""
        return self.prune is True or (isinstance(self.prune, frozenset) and (test.scene, test.protocol.name) in self.prune)

    def _run_intact(self, folder: Path, key: str, verify: bool) -> bool:
        """A run whose frames the report reads must be intact too (else it is re-made)."""
        if not verify:
            return True
        return self._complete(folder, key, verify_files=True) is not None

    def _complete(self, folder: Path, key: str, verify_files: bool = False, whole: bool = False) -> dict | None:
        """A folder's done record if it is complete (study.engine.store.Store.check); one found
        tampered is removed here, so that every task that reads it later sees it missing and makes
        it again (a task checks a record's seal, not every file it lists)."""
        from study.engine.store import TAMPERED
        got = self.store.check(folder, key, verify_files, whole)
        if got.status == TAMPERED:
            self.store.invalidate(folder, got.problem)
        return got.record

    def add_agreement(self, spec: str, scene, w: int, h: int, protocol: str) -> None:
        """The raster against frame 0's reference at the precision of `protocol`'s test (the static one)."""
        if not self.agreement_samples:
            return
        settings = self.settings(scene, protocol, 0)
        ref = self.reference_key(scene, 0, w, h, settings)
        disp = self.reference_key(scene, 0, w, h, self.display_settings)
        key = task_key("agreement", {"scene": scene.content_hash, "res": (w, h), "samples": self.agreement_samples},
                       [ref, disp], code=CODE["agreement"])
        path = self.store.record_path("agreement", scene.name, key)
        self.plan.agreements[scene.name] = key
        data = self.store.load_record(path, key)
        if data is not None:
            self.plan.cached[key] = {"kind": "agreement", "key": key, "data": data, "computed": False}
            return
        self.plan.tasks[key] = Task(key, AgreementSpec(
            self.ctx, spec, w, h, self.agreement_samples, settings, self.display_settings, key, str(path)),
            self._refs(spec, scene, w, h, [(0, settings)], [0]))

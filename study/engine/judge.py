"""The metrics task: one test's runs judged against their references (study.metrics.judging).

One task per (scene, protocol) judges every technique of the test whose metrics are missing, frame
by frame. Each reference is read, display-encoded and quantised once for all of them (at 1600x900
reading and encoding a reference costs about as much as the metrics of one technique-frame), and
the reference's half of SSIM and FLIP (its moments; its exposures and filtered planes) is computed
once per reference (their memos), a technique frame's own half once for the reference and its
two halves (study.metrics.judging.all_metrics_against); a technique's frames are read one at a time. Each technique's metrics are
still filed under their own key (its run, the references and the metric code), so a technique
added to a study is judged alone, and a key another task already judges is left to it (study.engine.plan).

Every figure is judged against the reference and against its two independent halves, and filed
with the reference's noise removed and the uncertainty that leaves (study.metrics.uncertainty).

A technique frame's figures against one reference (and display transform) are also kept by run
(`FrameFigures`): under the figures' rule a test is judged again each round some of its instants'
references are refined, and the frames whose reference did not change (at 320x180, 22 of
hairball_rotating_lit's 24 in its last round) take their figures from there instead of judging
again; only the temporal measure, which needs every frame in order, reads them all.

A run pruned once judged (its item's `keep`) keeps no float frame: the frames the report shows are
kept instead, by its metrics record, as the 8-bit display images they were judged as
(`shown_NNNN.png`, lossless for those 8 bits: at 1600x900 ~1.5 MB where the float frame took ~9;
docs/scale.md, "Disk"). The report and the paper show nothing else of a run.
"""
from __future__ import annotations

import contextlib
from pathlib import Path

from study.engine.tasks import TaskError, _deterministic, _setup, display_reference, load_scene
from study.metrics import judging as M
from study.metrics import temporal as T
from study.metrics import uncertainty as U


HALVES = ("", "a", "b")                 # the reference, and its two independent halves


def judged_references(ref, disp) -> dict:
    """What every technique frame is judged against: for the reference and each of its halves,
    (linear, display-encoded, 8-bit) under the one display transform `disp`."""
    from display import quantise
    out = {}
    for hv, lin in zip(HALVES, (ref.image, *ref.halves())):
        d = disp.encode(lin)
        out[hv] = (lin, d, quantise(d))            # disp.to_8bit, without encoding twice
    return out


@_deterministic
def metrics_task(ctx, scene_spec: str, w: int, h: int, items: list, ref_settings: dict, display_settings: dict,
                 deps=()) -> dict:
    """items: one per technique, {run_folder, run_key, frame_times (frame id -> scene time),
    maps_for (frame ids whose maps are kept), keep (frame ids of the run to keep once judged, or
    None for all), shown_8bit (those kept as the 8-bit images the report shows, in the metrics
    folder, and no float frame; else as float frames), hdr (judged in linear HDR too: Protocol.hdr),
    key, folder}. `ref_settings`: scene time -> the settings of its reference (each
    instant of a test has its own bound: study.engine.precision). Returns the records by metrics key."""
    store = _setup(ctx)
    scene = load_scene(scene_spec)
    with contextlib.ExitStack() as locks:
        records, todo = locked_records(store, items, locks)
        if todo:
            for it, data, reused in _judge(store, ctx, scene, w, h, todo, ref_settings, display_settings):
                records[it["key"]] = {"data": data, "computed": True, "frames_reused": reused}
    return {"kind": "metrics", "records": records}


def locked_records(store, items: list, locks) -> tuple[dict, list]:
    """Lock every item's key (in one order everywhere: no deadlock) on the ExitStack `locks`;
    returns (the records already complete, by key; the items still to compute, one per key: two
    columns of one configuration share their run and metrics, judged once)."""
    for key in sorted({it["key"] for it in items}):
        locks.enter_context(store.lock(key))
    records, todo = {}, []
    firsts: dict = {}
    for it in items:
        firsts.setdefault(it["key"], it)
    for it in firsts.values():
        rec = store.done(Path(it["folder"]), it["key"])
        if rec is not None:       # judged as its run was made, by this plan's run task: computed this round
            records[it["key"]] = {"data": rec["data"], "computed": it.get("mark") is not None
                                  and rec.get("judged_with_run") == it.get("mark")}
        else:
            todo.append(it)
    return records, todo


def _judge(store, ctx, scene, w, h, items: list, ref_settings: dict, display_settings: dict):
    import numpy as np

    from study.engine.store import TamperError
    runs = []
    for it in items:
        run = store.done(Path(it["run_folder"]), it["run_key"], whole=True)
        if run is None:
            raise TaskError(f"metrics of {it['run_folder']}: the run is not complete")
        runs.append(run)
    # Both protocols number a technique's frames in the order of their scene times, so judging by
    # time, then frame, keeps each sequence in order (the temporal measure needs it).
    by_time: dict = {}
    for i, (it, run) in enumerate(zip(items, runs)):
        times = {int(f): int(t) for f, t in it["frame_times"].items()}
        for f in run["frames"]:
            by_time.setdefault(times[f], []).append((i, f))
    judge = Judge(store, ctx, scene, w, h, items, [r["output_space"] for r in runs], ref_settings, display_settings)
    for t in sorted(by_time):
        for i, f in sorted(by_time[t]):
            it, run = items[i], runs[i]
            try:
                ch = store.read_image(Path(it["run_folder"]), f"frame_{f:04d}.exr", run)
            except TamperError as exc:
                store.invalidate(Path(it["run_folder"]), str(exc))
                raise TaskError(f"{exc}: the run was invalidated; run the study again to re-make it") from None
            judge.add(i, f, np.stack([ch[c] for c in "RGB"], -1))
    yield from judge.finish()


class Judge:
    """A test's techniques judged frame by frame as they come (`add`), by the metrics task from its
    runs' files or by the run task as it makes them (study.engine.run_task: no float frame is
    written), then filed (`finish`). Frames come in the order of their scene times (each run's in
    order: the temporal measure needs it); each reference is read once, when its time comes.
    `spaces`: each item's output space (display.DisplayTransform.output)."""

    def __init__(self, store, ctx, scene, w: int, h: int, items: list, spaces: list, ref_settings: dict,
                 display_settings: dict, with_run: bool = False):
        from references import ReferenceCache
        self.store, self.scene, self.w, self.h, self.items, self.spaces = store, scene, w, h, items, spaces
        self.ref_settings, self.display_settings = ref_settings, display_settings
        self.cache = ReferenceCache(Path(ctx.cache_root))
        self.times = [{int(f): int(t) for f, t in it["frame_times"].items()} for it in items]
        self.state = [{"per_frame": {}, "uncertainty": {}, "references": {},
                       "temporal": {h: T.TemporalInstability() for h in HALVES}} for _ in items]
        # a pruned run's shown frames, written as they are judged (no whole run's images held at once)
        self.writers = [store.writer(Path(it["folder"])) for it in items]
        self.shown = [set(it["keep"]) if it.get("keep") is not None and it.get("shown_8bit") else set()
                      for it in items]
        self.known = [FrameFigures(store, scene.name, it["run_key"], it.get("hdr", True)) for it in items]
        self.t, self.with_run = None, with_run      # with_run: judged by the run task as it made the run

    def _at(self, t: int) -> None:
        from display import DisplayTransform
        settings, cache = self.ref_settings[t], self.cache
        self.ref = cache.get(self.scene, t, self.w, self.h, **settings)[0]
        # one transform for all three; at a test's probe the reference is the probe: not read twice
        # (else display_of's, its reference's key kept for FrameFigures)
        if self.display_settings == settings:
            self.dkey, self.disp = self.ref.key, DisplayTransform.from_reference(self.ref.image)
        else:
            self.dkey, self.disp = display_reference(cache, self.scene, t, self.w, self.h, self.display_settings)
        self.refs = {hv: (*r, {}) for hv, r in judged_references(self.ref, self.disp).items()}   # {}: the memos
        self.t = t

    def add(self, i: int, f: int, x) -> None:
        """Judge frame `f` (an (H, W, 3) float image) of item `i`."""
        t = self.times[i][f]
        if t != self.t:
            self._at(t)
        it, st, ref, dkey, refs = self.items[i], self.state[i], self.ref, self.dkey, self.refs
        x_lin, x_disp, x8 = self.disp.output(x, self.spaces[i])
        if f in self.shown[i]:
            self.writers[i].add_png(f"shown_{f:04d}.png", x8)
        keep = [hv == "" and f in it["maps_for"] for hv in refs]
        figs = None if any(keep) else self.known[i].get(f, ref.key, dkey)
        if figs is None:
            judged = M.all_metrics_against(list(refs.values()), x_lin, x_disp, x8, want_maps=keep,
                                           hdr=it.get("hdr", True))
            figs = {hv: got for hv, (got, _) in zip(refs, judged)}
            for (_, maps), k in zip(judged, keep):    # written now: a static test's 25 columns held ~1.5 GB
                if k:
                    self.writers[i].add(f"maps_{f:04d}.exr", maps)
            self.known[i].put(f, ref.key, dkey, figs)
        for hv, (_, _, r8, _) in refs.items():
            st["temporal"][hv].add(r8, x8)
        st["per_frame"][str(f)], st["uncertainty"][str(f)] = U.jackknife(figs[""], figs["a"], figs["b"])
        st["references"][str(t)] = ref.key

    def finish(self):
        """File each item's metrics (and prune its run to what the report shows, if asked); yields
        (item, data, frames whose figures an earlier round's judging gave)."""
        store = self.store
        for it, st, kn, wr in zip(self.items, self.state, self.known, self.writers):
            kn.save()
            tm = {hv: (acc.value() if acc.frames > 1 else None) for hv, acc in st["temporal"].items()}
            temporal = temporal_u = None
            if tm[""] is not None:
                c, u = U.jackknife(*({"temporal": tm[hv]} for hv in HALVES))
                temporal, temporal_u = c["temporal"], u["temporal"]
            data = {"per_frame": st["per_frame"], "uncertainty": st["uncertainty"], "temporal": temporal,
                    "temporal_u": temporal_u, "references": st["references"]}
            rec = wr.seal(it["key"], {"data": data, **({"judged_with_run": it.get("mark")} if self.with_run else {})})
            if it.get("keep") is not None:   # judged: only what the report shows stays (study.engine.plan)
                # as shown, above; as float frames where the video metric reads them too
                keep = set() if it.get("shown_8bit") else {f"frame_{f:04d}.exr" for f in it["keep"]}
                store.prune(Path(it["run_folder"]), it["run_key"], keep)
            yield it, rec["data"], kn.reused


class FrameFigures:
    """The figures of a run's frames against each reference (and display transform) they were
    judged against, the reference's and its halves': `get` what an earlier metrics task of the
    same run judged, `put` what this one did, `save` merges them into the run's record under its
    lock (two tasks may judge one run). Keyed by the run and the metric code: a frame's figures
    depend on nothing else but the two reference keys."""

    def __init__(self, store, scene: str, run_key: str, hdr: bool = True):
        from provenance import task_key
        from study.engine.plan import CODE
        self.store, self.key = store, task_key("frame-figures", {} if hdr else {"hdr": False}, [run_key],
                                               code=CODE["metrics"])
        self.path = store.record_path("frame-figures", scene, self.key)
        self.old = (store.load_record(self.path, self.key) or {}).get("figures", {})
        self.new: dict = {}
        self.reused = 0

    def get(self, frame: int, ref_key: str, disp_key: str) -> dict | None:
        got = self.old.get(f"{frame} {ref_key} {disp_key}")
        self.reused += got is not None
        return got

    def put(self, frame: int, ref_key: str, disp_key: str, figs: dict) -> None:
        self.new[f"{frame} {ref_key} {disp_key}"] = figs

    def save(self) -> None:
        if not self.new:
            return
        with self.store.lock(self.key):
            now = (self.store.load_record(self.path, self.key) or {}).get("figures", {})
            self.store.save_record(self.path, self.key, {"figures": {**now, **self.new}})

"""The run task: techniques that share raster frames run over one protocol on one scene, each
judged frame filed in the cache as it is made, or, for a run pruned once judged, judged as it is made
(study.engine.judge.Judge): such a run never holds a float frame on disk (at 1600x900 a ghosting
test's seven 100-frame runs took ~6 GB until judged; docs/scale.md, "Disk")."""
from __future__ import annotations

import contextlib
from pathlib import Path

from provenance import task_key
from study.engine.drive import run_schedule
from study.engine.tasks import Context, _deterministic, _setup, display_of, load_scene


@_deterministic
def run_task(ctx: Context, scene_spec: str, w: int, h: int, protocol, configs: list, keys: dict,
             folders: dict, display_settings: dict, feeds: dict | None = None, judge: list | None = None,
             deps=()) -> dict:
    """Run the techniques `configs` (sharing raster frames) over `protocol` on one scene; file each
    technique's judged frames under its key. A display-space technique sees each frame's display
    transform (study.engine.tasks.display_of). `feeds`: label -> the (metrics folder, key) its run
    is judged into; a run another study made, judged and pruned meanwhile is not made again.
    `judge`: [{'items': metrics items (study.engine.judge.metrics_task), 'ref_settings': scene time
    -> its reference's settings}], one per test: the runs those items read are judged as they are
    made (their references made first), and keep no float frame (their done record lists every
    frame as pruned). Returns label -> done record summary."""
    store = _setup(ctx)
    scene = load_scene(scene_spec)
    out, todo = {}, []
    # a lock per run, not per task: a study planned while another was sealing this task's runs one
    # by one groups the rest differently, and a per-task lock let both compute them (tested)
    with contextlib.ExitStack() as locks:
        for lock in sorted(task_key("run-lock", k) for k in set(keys.values())):   # one order: no deadlock
            locks.enter_context(store.lock(lock))
        for c in configs:
            rec = store.done(Path(folders[c.label]), keys[c.label], whole=True)
            judged = (feeds or {}).get(c.label)
            if rec is None and judged and all(store.done(Path(f), k) is not None for f, k in judged):
                rec = store.done(Path(folders[c.label]), keys[c.label])
            if rec is not None:
                out[c.label] = _run_summary(rec, computed=False)
            elif all(keys[t.label] != keys[c.label] for t in todo):   # two columns of one configuration: made once
                todo.append(c)
        if todo:
            schedule = protocol.schedule(scene)
            displays = {}
            if any(c.inputs().display for c in todo):
                from references import ReferenceCache
                cache = ReferenceCache(Path(ctx.cache_root))
                for t in sorted({s.t for s in schedule if s.keep}):   # one reference held at a time
                    displays[t] = display_of(cache, scene, t, w, h, display_settings)
            writers = {c.label: store.writer(Path(folders[c.label])) for c in todo}
            frames: dict = {c.label: [] for c in todo}
            judges, judged = _judges(store, ctx, scene, w, h, todo, keys, display_settings, judge or [], locks)
            # no float frame for a run every metrics key it feeds is judged here (or already was)
            streamed = {c.label for c in todo if (feeds or {}).get(c.label)
                        and all(k in judged for _, k in feeds[c.label])}

            def emit(label, f, img):      # each judged frame, checked (study.engine.drive), is judged or filed
                for j, of in judges:
                    for i in of.get(label, ()):
                        j.add(i, f, img)
                if label not in streamed:
                    writers[label].add(f"frame_{f:04d}.exr", img)
                frames[label].append(f)
            fresh = run_schedule(scene, w, h, schedule, todo, displays,
                                 desc=f"{scene.name}: {protocol.name} ({', '.join(c.label for c in todo)})",
                                 progress=False, emit=emit)
            for j, _ in judges:       # the metrics first: a run found pruned is made again
                for _ in j.finish():
                    pass
            for c in todo:
                r = fresh[c.label]
                meta = {"label": c.label, "technique": c.name, "overrides": [list(o) for o in c.overrides],
                        "output_space": r["output_space"], "nonfinite_inputs": r["nonfinite"],
                        "frames": sorted(frames[c.label]), "stats": {str(f): v for f, v in r["stats"].items()}}
                if c.label in streamed:
                    meta["pruned"] = [f"frame_{f:04d}.exr" for f in sorted(frames[c.label])]
                rec = writers[c.label].seal(keys[c.label], meta)
                out[c.label] = _run_summary(rec, computed=True)
            for c in configs:       # a column of the same configuration as one made here
                if c.label not in out:
                    made = next(t.label for t in todo if keys[t.label] == keys[c.label])
                    out[c.label] = {**out[made], "computed": False}
    return {"kind": "run", "runs": out}


def _judges(store, ctx, scene, w: int, h: int, todo: list, keys: dict, display_settings: dict, judge: list,
            locks) -> tuple[list, set]:
    """([(study.engine.judge.Judge, label -> its item indices)] for the groups of `judge` whose items
    read a run made here and are not judged yet (their metrics keys locked on `locks`), the metrics
    keys those judge or found judged)."""
    from study.engine.judge import Judge, locked_records
    made = {keys[c.label]: c for c in todo}
    out, judged = [], set()
    for group in judge:
        done, items = locked_records(store, [it for it in group["items"] if it["run_key"] in made], locks)
        judged |= set(done) | {it["key"] for it in items}
        if not items:
            continue
        of: dict = {}
        for i, it in enumerate(items):
            of.setdefault(made[it["run_key"]].label, []).append(i)
        spaces = [made[it["run_key"]].inputs().output_space for it in items]
        out.append((Judge(store, ctx, scene, w, h, items, spaces, group["ref_settings"], display_settings,
                         with_run=True), of))
    return out, judged


def _run_summary(rec: dict, computed: bool) -> dict:
    return {"key": rec["key"], "frames": rec["frames"], "output_space": rec["output_space"],
            "stats": rec.get("stats", {}), "computed": computed}

"""The run task: techniques that share raster frames run over one protocol on one scene, each
judged frame filed in the cache as it is made."""
from __future__ import annotations

import contextlib
from pathlib import Path

from provenance import task_key
from study.engine.drive import run_schedule
from study.engine.tasks import Context, _deterministic, _setup, display_of, load_scene


@_deterministic
def run_task(ctx: Context, scene_spec: str, w: int, h: int, protocol, configs: list, keys: dict,
             folders: dict, display_settings: dict, feeds: dict | None = None, deps=()) -> dict:
    """Run the techniques `configs` (sharing raster frames) over `protocol` on one scene; file each
    technique's judged frames under its key. A display-space technique sees each frame's display
    transform (study.engine.tasks.display_of). `feeds`: label -> the (metrics folder, key) its run
    is judged into; a run another study made, judged and pruned meanwhile is not made again.
    Returns label -> done record summary."""
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
            if any(c.make().inputs.display for c in todo):
                from references import ReferenceCache
                cache = ReferenceCache(Path(ctx.cache_root))
                for t in sorted({s.t for s in schedule if s.keep}):   # one reference held at a time
                    displays[t] = display_of(cache, scene, t, w, h, display_settings)
            writers = {c.label: store.writer(Path(folders[c.label])) for c in todo}
            frames: dict = {c.label: [] for c in todo}

            def emit(label, f, img):      # each judged frame, checked (study.engine.drive), goes to the cache
                writers[label].add(f"frame_{f:04d}.exr", img)
                frames[label].append(f)
            fresh = run_schedule(scene, w, h, schedule, todo, displays,
                                 desc=f"{scene.name}: {protocol.name} ({', '.join(c.label for c in todo)})",
                                 progress=False, emit=emit)
            for c in todo:
                r = fresh[c.label]
                meta = {"label": c.label, "technique": c.name, "overrides": [list(o) for o in c.overrides],
                        "output_space": r["output_space"], "nonfinite_inputs": r["nonfinite"],
                        "frames": sorted(frames[c.label]), "stats": {str(f): v for f, v in r["stats"].items()}}
                rec = writers[c.label].seal(keys[c.label], meta)
                out[c.label] = _run_summary(rec, computed=True)
            for c in configs:       # a column of the same configuration as one made here
                if c.label not in out:
                    made = next(t.label for t in todo if keys[t.label] == keys[c.label])
                    out[c.label] = {**out[made], "computed": False}
    return {"kind": "run", "runs": out}


def _run_summary(rec: dict, computed: bool) -> dict:
    return {"key": rec["key"], "frames": rec["frames"], "output_space": rec["output_space"],
            "stats": rec.get("stats", {}), "computed": computed}

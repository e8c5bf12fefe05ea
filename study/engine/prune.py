"""Pruning a planned study's runs once their tests settle: only the frames the report shows stay."""
from __future__ import annotations

from pathlib import Path

from provenance import task_key


def prune_runs(planner, settled) -> int:
    """Prune the runs of the tests of `planner` (study.engine.plan.Planner) for which
    `settled((scene, protocol))` holds to the frames they keep: a run several tests read (a shared
    run) keeps the union of theirs, and only once all of them have settled. Returns the files dropped."""
    keep: dict = {}
    for t in planner.plan.tests:
        for label, folder in t.run_folders.items():
            k = keep.setdefault((folder, t.run_keys[label]), {"frames": set(), "whole": False, "settled": True})
            k["settled"] &= bool(settled((t.scene, t.protocol.name)))
            if t.keep[label] is None:
                k["whole"] = True
            else:
                k["frames"] |= set(t.keep[label])
    dropped = 0
    for (folder, key), k in keep.items():
        if k["settled"] and not k["whole"]:
            names = {f"frame_{f:04d}.exr" for f in k["frames"]}
            rec = planner.store.done(Path(folder), key)
            if rec is None or set(rec["files"]) <= names:     # nothing to drop: no lock to take
                continue
            with planner.store.lock(task_key("run-lock", key)):      # as run_task, which (re)makes it
                dropped += planner.store.prune(Path(folder), key, names)
    return dropped

"""Superseded artefacts: what a study no longer reads once the precision loop refines a test's
references (`keep_superseded = false`, the thesis profile; docs/scale.md, "Disk").

When a round renders an instant's reference at a finer bound, the reference at the coarser bound
(one file, its halves' difference inside it) and the metrics records judged against it (their
SSIM/FLIP maps and shown frames) are read by no later round of the study. They are removed once
the round that replaces them is planned, before it renders: what the previous round's plan read
(`held`) and this round's does not. Anything this round's plan reads stays: a reference another
test or instant uses at that bound, a frame a reference chain keeps pixels of (references.reuse:
the same bound only). The probe's references, which the display transforms come from, go too once
refined past: each filed its transform (references.cache: `<key>.display.json`, kept), which is
all a later round reads of it. A removed file or folder is first renamed to a trash name (one
atomic step: a reader finds it whole or missing, never half), then deleted. The disk then holds
one round's references, not every round's, nor the probe's beside the finer ones (the figures'
rounds: docs/scale.md, "Disk").

A killed study must not need them again: before that round starts, the state the precision loop
carries (`save_progress`) is filed under the study's inputs, and a resumed study starts from it
(`resume`): at the finer bounds, never at the coarser ones removed.
"""
from __future__ import annotations

import os
import shutil
import uuid
from pathlib import Path

from study.engine.disk import used_bytes
from study.engine.rounds import FigureKey, InstantKey, Over, TestKey


def reference_paths(cache, scene, t: int, w: int, h: int, settings: dict, memo: dict | None = None) -> list[Path]:
    """The files instant t's reference at `settings` reads (references.cache.ReferenceCache.chain):
    its own and, where it keeps the previous frame's pixels, each earlier frame's of its chain.
    `memo`: keys already found (a test's instants share their chains)."""
    return [cache.path(scene, k) for k in cache.settings_chain(scene, t, w, h, **settings, memo=memo)]


def held(study, rnd) -> set[Path]:
    """Every reference file and metrics folder the round's plan reads: its tests' references at each
    judged instant (their chains too) and the display's where no display record stands for it, the
    references its tasks render, the metrics records it judges."""
    from references.cache import display_path, extremes_path
    from study.engine.tasks import load_scene
    cache, out, scenes, memo = study.cache, set(), {}, {}
    scene_of = lambda spec: scenes.setdefault(spec, load_scene(spec))    # noqa: E731
    for test in rnd.plan.tests:
        scene = scene_of(test.spec)
        for t, s in test.ref_settings_at.items():
            out.update(reference_paths(cache, scene, t, test.width, test.height, s, memo))
            disp = reference_paths(cache, scene, t, test.width, test.height, study.display_settings, memo)
            if not display_path(disp[-1]).exists():     # else its transform is read from its record
                out.update(disp)
        out.update(Path(f) for f in test.metrics_folders.values())
    for task in rnd.plan.tasks.values():
        if task.kind == "reference":
            sp = task.spec
            out.update(reference_paths(cache, scene_of(sp.scene), sp.t, sp.width, sp.height, sp.settings, memo))
    for spec, scene in rnd.scenes:       # frame 0's reference at the static test's bound (the report's)
        w, h = study.resolution(scene)
        out.update(reference_paths(cache, scene, 0, w, h, study.settings_for(scene.name), memo))
    refs = cache.root / "references"
    return out | {extremes_path(p) for p in out if p.parent.parent == refs}     # their extremes, where kept


def _held(study, rnd) -> set[Path]:
    """`held` of a Round, or a set of paths as filed (what a killed study's last round read);
    remembered per Round (each is asked twice: as `now`, then as the next round's `before`)."""
    if isinstance(rnd, set):
        return rnd
    memo = study.__dict__.setdefault("_held_of", {})
    if id(rnd) not in memo or memo[id(rnd)][0] is not rnd:
        memo[id(rnd)] = (rnd, held(study, rnd))
        while len(memo) > 2:          # this round's and the one before
            memo.pop(next(iter(memo)))
    return memo[id(rnd)][1]


def remove(paths, root: Path) -> tuple[int, int]:
    """Delete each file or folder of `paths` that exists, renamed first to a trash name under
    `root` (atomic: no reader sees it half deleted). Returns (how many, bytes freed)."""
    trash = Path(root) / "trash"
    trash.mkdir(parents=True, exist_ok=True)
    n = freed = 0
    for p in sorted(paths):
        gone = trash / f"{uuid.uuid4().hex}-{p.name}"
        try:
            os.replace(p, gone)
        except FileNotFoundError:
            continue
        n += 1
        if gone.is_dir():
            freed += used_bytes(gone)
            shutil.rmtree(gone, ignore_errors=True)
        else:
            freed += gone.stat().st_size
            gone.unlink(missing_ok=True)
    try:
        trash.rmdir()           # emptied (another study's removal may still be using it)
    except OSError:
        pass
    return n, freed


def removing(study) -> bool:
    """Whether the study removes superseded artefacts (keep_superseded false, the figures' rule)."""
    return not study.profile.keep_superseded and study.precision.rule == "figures"


def superseded(study, before, now) -> set[Path]:
    """What the previous round's plan `before` read and the round `now` does not (Rounds): empty
    where nothing is removed. Remembered for `now` (fit prices the disk with it, then it is removed)."""
    if not removing(study) or before is None:
        return set()
    memo = getattr(study, "_superseded", None)
    if memo is None or memo[0] is not now:
        study._superseded = memo = (now, _held(study, before) - _held(study, now))
    return memo[1]


def freeable(study, before, now) -> int:
    """The bytes removing `superseded(study, before, now)` frees (what the disk check adds to the free)."""
    n = 0
    for p in superseded(study, before, now):
        try:
            n += used_bytes(p) if p.is_dir() else p.stat().st_size
        except FileNotFoundError:
            pass
    return n


def before_round(study, before, now):
    """The round `now` is planned (and the state it starts from filed: `file_progress`): remove what
    `before` read that it does not. Done before `now` renders, not after: no later round of the
    study reads them (a killed study resumes at `now`'s bounds), and the disk then holds one
    round's references, not two. Returns `now`."""
    gone = superseded(study, before, now)
    if gone:
        n, freed = remove(gone, study.cache.root)
        study.log(f"disk: {n} references and metrics records a finer bound superseded removed "
                  f"({freed / 2 ** 20:.1f} MB; keep_superseded = false)")
    return now


# -- the precision loop's state, filed so a killed study resumes at its finer bounds ---------------------
def _path(store, inputs: str) -> Path:
    return store.record_path("precision", "progress", inputs)


def save_progress(store, inputs: str, state, paths=()) -> None:
    """File the state the next round starts from (levels, bounds tried, figures over tolerance,
    drifts, the figures judged last, the tests settled early, the probes' and decisions' keys) and
    `paths`, what the last round read (under the store's root)."""
    def tk(k):
        return [*k] if isinstance(k, InstantKey) else [*k, None]
    memo = state.memo or {}
    rec = {"levels": [[*tk(k), n] for k, n in state.levels.items()],
           "tried": [[*k, list(v)] for k, v in state.tried.items()],
           "over": [[*k, [list(x) for x in v]] for k, v in state.over.items()],
           "drifts": [[*k, [[*f, d] for f, d in v.items()]] for k, v in state.drifts.items()],
           "before": [[*k, sorted([[t, b] for t, b in bounds.items()]), [[*f, *vu] for f, vu in figs.items()]]
                      for k, (bounds, figs) in state.before.items()],
           "early": sorted([*k] for k in state.early),
           "probes": [[*k, list(v)] for k, v in (state.probes or {}).items()],
           "decisions": memo.get("key"), "final": bool(state.final),
           "held": sorted(os.path.relpath(p, store.root) for p in paths)}
    store.save_record(_path(store, inputs), inputs, rec)


def load_progress(store, inputs: str) -> dict | None:
    """The fields of Progress (and the decisions record's key) a killed study of these inputs filed
    with `save_progress`, or None."""
    rec = store.load_record(_path(store, inputs), inputs)
    if rec is None:
        return None
    levels = {(TestKey(s, p) if t is None else InstantKey(s, p, t)): int(n) for s, p, t, n in rec["levels"]}
    return {"levels": levels,
            "tried": {TestKey(s, p): list(v) for s, p, v in rec["tried"]},
            "over": {TestKey(s, p): [Over(*x) for x in v] for s, p, v in rec["over"]},
            "drifts": {TestKey(s, p): {FigureKey(*d[:-1]): d[-1] for d in v} for s, p, v in rec["drifts"]},
            "before": {TestKey(s, p): ({t: b for t, b in bounds}, {FigureKey(*f[:4]): tuple(f[4:]) for f in figs})
                       for s, p, bounds, figs in rec["before"]},
            "early": frozenset(TestKey(*k) for k in rec["early"]),
            "probes": {TestKey(s, p): list(v) for s, p, v in rec["probes"]},
            "decisions": rec.get("decisions"), "final": bool(rec.get("final")), "held": rec.get("held", [])}


def resume(study, inputs: str) -> dict | None:
    """Progress's fields to start a killed study of these inputs from (`load_progress`, its
    decisions record's place as precision.decisions gives it), or None. What its last round read
    is set on the study (`_resumed`): what the resumed round no longer reads is removed then."""
    from study.engine.store import Store
    store = Store(study.cache.root)
    got = load_progress(store, inputs)
    if got is None:
        return None
    key, paths = got.pop("decisions"), got.pop("held")
    study._resumed = {store.root / p for p in paths}
    study.log("precision: resuming at the bounds a killed study of the same inputs had reached (its coarser "
              "references removed: keep_superseded = false)")
    return {**got, "memo": None if key is None else {
        "store": store, "path": store.record_path("precision", "decisions", key), "key": key, "replayed": None}}


def file_progress(study, state, rnd) -> None:
    """File the state the next round starts from and what the round `rnd` read, where superseded
    artefacts are removed."""
    from study.engine.store import Store
    if removing(study) and state.inputs and not state.finished:
        save_progress(Store(study.cache.root), state.inputs, state, _held(study, rnd))


def forget_progress(store, inputs: str | None) -> None:
    """The study finished: its decisions are filed (precision.remember), its progress is not needed."""
    if inputs:
        _path(store, inputs).unlink(missing_ok=True)

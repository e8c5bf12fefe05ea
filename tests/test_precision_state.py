"""The precision loop's typed state and the tasks as data: decide returns a new state and leaves
its arguments as they were; test, instant and figure keys are named records; each planned task is
a frozen, picklable spec read by name; the store reports a tampered record and the caller removes it."""
import copy
import pickle
from pathlib import Path

import numpy as np
import pytest

from study.config.precision import Precision


def test_decide_returns_a_new_state_and_leaves_its_arguments_untouched():
    from study.engine.precision import decide
    from study.engine.rounds import FigureKey, InstantKey, TestKey
    G = TestKey("s", "ghosting")
    inst = {G: {("X", 0): 10, ("X", 1): 11}}
    f0, tr = ("ghosting", "X", 0, "flip_hdr"), ("ghosting", "X", None, "temporal")
    now = {G: {f0: (0.1, 4e-4), tr: (10.0, 0.001)}}
    # a round before at 8 LSB, with a drift already kept for the temporal RMS
    before = {G: ({10: 8.0, 11: 8.0}, {f0: (0.1004, 5e-4)})}
    levels = {G: 0, InstantKey("s", "ghosting", 10): 3}
    over, drifts = {G: [("old",)]}, {G: {FigureKey(*tr): 1e-4}}
    args = (now, before, levels, Precision(), over, drifts, inst)
    kept = copy.deepcopy(args[:2] + args[2:3] + args[4:])
    d = decide(*args)
    assert (now, before, levels, over, drifts, inst) == kept          # nothing filled in place
    assert d.judged == {G} and d.finer == {G: {10: 6}}               # frame 0's FLIP: 4e-4 at 1 LSB asks 3 more
    assert d.before[G][0] == {10: 1.0, 11: 8.0} and before[G][0] == {10: 8.0, 11: 8.0}
    assert d.drifts[G][f0] == 0.0 and d.drifts[G][tr] == 1e-4 and drifts[G] == {tr: 1e-4}   # tr's kept
    assert [x[:4] for x in d.over[G]] == [f0] and over[G] == [("old",)]
    assert d.over[G][0].metric == "flip_hdr" and d.over[G][0].tolerance < d.over[G][0].uncertainty
    assert all(type(f) is FigureKey for f in d.drifts[G])


def test_keys_are_named_records_and_a_decisions_record_restores_them():
    from study.engine.precision import from_record, level_at, to_record
    from study.engine.rounds import FigureKey, InstantKey, TestKey, instant_levels
    A = TestKey("s", "static")
    i = InstantKey("s", "static", 3)
    assert i.test == A and i == ("s", "static", 3) and A == ("s", "static")      # lookups by plain tuples still hit
    levels = {A: 2, i: 4, InstantKey("t", "static", 3): 1}
    assert instant_levels(levels, A) == {3: 4} and level_at(levels, A, 3) == 4 and level_at(levels, A, 5) == 2
    rec = to_record(levels, {A: [8.0, 2.0]}, {A: []}, {A: {FigureKey("static", "X", 8, "psnr"): 0.01}})
    got, tried, over, drifts = from_record(rec)
    assert got == {A: 2, i: 4} and tried == {A: [8.0, 2.0]}
    assert {type(k) for k in got} == {TestKey, InstantKey} and type(next(iter(drifts[A]))) is FigureKey
    over = to_record({A: 0}, {A: [8.0]}, {A: [("static", "X", 8, "psnr", 0.2, 0.1)]}, {})
    assert from_record(over)[2][A][0].uncertainty == 0.2                 # an Over, by name


def _planned(tmp_path):
    from study.config.protocols import Protocol
    from study.config.techniques import TechniqueConfig
    from study.engine.plan import Planner
    from study.engine.tasks import Context, load_scene
    base = {"se_bound_lsb": 8.0, "target_noise_db": 0.0, "held_out": True}
    pl = Planner(Context(str(tmp_path), 1), base, 4, {}, base)
    proto = Protocol("static", "static", history=2, checkpoints=(2,))
    test = pl.add_test("pipe", load_scene("pipe"), proto, [TechniqueConfig.parse("FXAA=fxaa")], 16, 9)
    pl.add_agreement("pipe", load_scene("pipe"), 16, 9, "static")
    return pl, test


def test_each_task_is_a_frozen_picklable_spec_read_by_name(tmp_path):
    import dataclasses

    from study.engine import disk as D
    from study.engine.specs import SPECS
    pl, test = _planned(tmp_path)
    tasks = pl.plan.tasks.values()
    assert {t.kind for t in tasks} == {"reference", "run", "metrics", "agreement"}
    for t in tasks:
        assert type(t.spec) in SPECS and t.kind == type(t.spec).kind
        assert pickle.loads(pickle.dumps(t.spec)) == t.spec          # a Dask worker gets the same call
        with pytest.raises(dataclasses.FrozenInstanceError):
            t.spec.width = 1
    run = next(t.spec for t in tasks if t.kind == "run")
    assert run.keys == test.run_keys and run.scene == "pipe" and (run.width, run.height) == (16, 9)
    refs = [t.spec for t in tasks if t.kind == "reference"]
    assert sorted(r.t for r in refs) == sorted(test.reference_tasks)
    # the disk a plan needs, from the specs' fields: every reference is new here
    assert not any(r.settings.get("reuse") for r in refs)     # a still scene: no extremes kept
    assert D.needs(pl.plan)["references"] == sum(D.file_bytes("reference", 16, 9, scene=r.scene) for r in refs)


def test_a_tampered_record_is_reported_and_removed_only_by_the_caller(tmp_path):
    from study.engine import store as S
    logs = []
    st = S.Store(tmp_path, log=logs.append)
    folder = tmp_path / "runs" / "x" / "k"
    st.save_folder(folder, "k", {"frame_0000.exr": np.zeros((2, 2, 3), np.float32)}, {"frames": [0]})
    assert st.check(folder, "k", verify_files=True).status == S.COMPLETE
    assert st.check(folder, "other").status == S.OTHER_KEY and st.check(tmp_path / "no", "k").status == S.MISSING
    path = folder / "frame_0000.exr"
    path.write_bytes(path.read_bytes()[:-1] + b"\0")
    got = st.check(folder, "k", verify_files=True)
    assert got.status == S.TAMPERED and got.record is None and "expected SHA-256" in got.problem
    assert st.done(folder, "k", verify_files=True) is None and "expected SHA-256" in logs[-1]
    assert (folder / "done.json").exists()                     # reported, not deleted
    st.invalidate(folder, got.problem)                          # the caller's decision
    assert st.check(folder, "k").status == S.MISSING


def test_the_planner_removes_a_tampered_run_it_finds(tmp_path):
    """The planner checks a run's files; a task later checks only its record's seal: the planner
    removes what it found tampered, so that the task makes it again rather than reading it."""
    pl, test = _planned(tmp_path)
    from study.engine.store import Store
    folder, key = Path(test.run_folders["FXAA"]), test.run_keys["FXAA"]
    Store(tmp_path).save_folder(folder, key, {"frame_0002.exr": np.zeros((9, 16, 3), np.float32)}, {"frames": [2]})
    (folder / "frame_0002.exr").write_bytes(b"not an exr")
    assert pl._complete(folder, key, verify_files=True) is None
    assert not (folder / "done.json").exists()

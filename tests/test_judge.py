"""study.engine.judge: a test's techniques judged together, each reference read once, the same figures as
judging each run alone (metrics.judge_run, the whole-sequence form)."""
import functools
import json
import math
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from study.metrics import uncertainty as U
from study_fixtures import quick_every_frame, write_scenes
from test_estimate import STUDY


def test_one_metrics_task_per_test_reads_each_reference_once_and_agrees_with_judge_run(tmp_path, monkeypatch):
    from display import DisplayTransform
    from references import cache as rc
    from study.metrics import judging as M
    from study.config.profile import get_profile
    from study.config.techniques import TechniqueConfig
    from study.engine.runner import Study
    from study.engine.store import Store

    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    scenes = write_scenes(tmp_path)
    path = tmp_path / "units.toml"
    # every frame kept: judge_run reads them below
    path.write_text(STUDY.format(scenes=json.dumps(scenes)).replace("sweep = false\n", 'sweep = false\nkeep_frames = "all"\n'))
    reads = []
    get = rc.ReferenceCache.get

    @functools.wraps(get)       # the study file's reference fields are checked against get's signature
    def counting_get(self, scene, t, *a, **k):
        import sys
        if sys._getframe(1).f_code.co_filename.endswith("judge.py"):
            reads.append((scene.name, t))
        return get(self, scene, t, *a, **k)
    monkeypatch.setattr(rc.ReferenceCache, "get", counting_get)
    configs = [TechniqueConfig.parse(s) for s in ("taa_baseline", "noaa", "fxaa")]
    study = Study(get_profile(str(path)), cache_root=tmp_path / "cache", progress=False)
    res = study.run(scenes, configs, agreement=False)
    assert res.stats["tasks"]["metrics"] == 4               # 2 static tests, cold and warm ghosting
    # where the time went, by task kind: every kind that ran, positive, and no kind that did not
    assert set(res.stats["task_seconds"]) == set(res.stats["tasks"]) and min(res.stats["task_seconds"].values()) > 0
    # and by scene: the two scenes' shares add up to each kind's total
    by_scene = res.stats["task_seconds_by_scene"]
    assert set(by_scene) == {"tiny_moving", "tiny_still"}
    for kind, total in res.stats["task_seconds"].items():
        assert sum(k.get(kind, 0.0) for k in by_scene.values()) == pytest.approx(total, abs=0.05)
    assert res.stats["metrics_computed"] == 2 * 3 + 3 + 1   # warm: No AA and FXAA are the cold runs
    # per task each scene time once: static t 0 (x2 scenes), cold t 0..3, warm t 0..3
    assert sorted(reads) == sorted([("tiny_moving", 0), ("tiny_still", 0)] + [("tiny_moving", t) for t in range(4)] * 2)

    store = Store(tmp_path / "cache")
    static = next(t for t in res.statics if t.scene == "tiny_moving")
    for test in (res.ghosts["ghosting"][0], res.ghosts["ghosting_warm"][0], static):
        for label in ("taa_baseline", "fxaa"):
            proto = test.test
            art = test.artefacts[label]
            run = store.done(Path(art["folder"]), art["run_key"])
            images = {f: np.stack([store.read_image(Path(art["folder"]), f"frame_{f:04d}.exr", run)[c]
                                   for c in "RGB"], -1) for f in run["frames"]}
            # judge_run takes frame ids for scene times: the static test's frames (history lengths) all show t 0
            refs = {f: study.reference(study_scene(scenes[0]), f if test.kind == "ghosting" else 0,
                                       test.width, test.height) for f in images}
            # every frame under its probe's transform (study.engine.tasks.display_of)
            disp = {f: DisplayTransform.from_reference(study.cache.get(
                study_scene(scenes[0]), f if test.kind == "ghosting" else 0, test.width, test.height,
                **study.display_settings)[0].image) for f in refs}
            # against the reference and its two halves (the judge removes the reference's bias with them)
            by_half = []
            for h in range(3):
                imgs = {t: SimpleNamespace(image=(r.image, *r.halves())[h]) for t, r in refs.items()}
                ref8 = {t: disp[t].to_8bit(imgs[t].image) for t in imgs}
                by_half.append(M.judge_run(images, run["output_space"], imgs, disp, ref8, sorted(images))[0])
            for f in images:
                want, want_u = U.jackknife(*(b["per_frame"][str(f)] for b in by_half))
                for k, v in want.items():
                    got = test.per_frame[label][f][k]
                    if test.kind == "ghosting" and k in ("flip_hdr", "relmse_hdr"):
                        assert got is None, (proto, label, f, k)     # printed by no ghosting table: not judged
                        continue
                    assert (got is None and v is None) or got == pytest.approx(v, rel=1e-12, abs=1e-12), (proto, label, f, k)
                    gu = test.uncertainty[label][f][k]
                    assert (gu is None and want_u[k] is None) or gu == pytest.approx(want_u[k], rel=1e-9, abs=1e-12)
            if len(images) > 1:
                want_t, _ = U.jackknife(*({"temporal": b["temporal"]} for b in by_half))
                assert test.temporal[label] == pytest.approx(want_t["temporal"], rel=1e-12)
                assert math.isfinite(test.temporal[label]) and test.temporal[label] > 0


def study_scene(spec):
    from study.engine.tasks import load_scene
    return load_scene(spec)


@pytest.mark.long(seconds=25)
def test_runs_keep_only_the_frames_the_report_reads_and_are_remade_when_judged_again(tmp_path, monkeypatch):
    from study.config.profile import get_profile
    from study.config.techniques import TechniqueConfig
    from study.engine.plan import shown_frames
    from study.engine.runner import Study
    from study.engine.store import Store
    from study_fixtures import moving_scene

    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    scene = tmp_path / "long.toml"
    scene.write_text(moving_scene(frames=26, size=(24, 16)))       # more frames than the report shows
    path = tmp_path / "s.toml"
    # no video metric (STUDY has none): it keeps every judged frame of the runs it reads (study.engine.plan)
    assert '[video]\nmetric = "none"' in STUDY
    # references at 2 LSB: which frames a run keeps, and the figures of one re-made, do not depend on them
    path.write_text(STUDY.format(scenes=json.dumps([str(scene)])).replace("frames = 4", "frames = 26")
                    + "[reference]\nse_bound_lsb = 2.0\ntarget_noise_db = 0.0\n")
    configs = [TechniqueConfig.parse(s) for s in ("taa_baseline", "noaa")]

    def run():
        study = Study(get_profile(str(path)), cache_root=tmp_path / "cache", progress=False)
        return study.run([str(scene)], configs, agreement=False)
    first = run()
    store = Store(tmp_path / "cache")

    def files(test, label):
        a = test.artefacts[label]
        rec = store.done(Path(a["folder"]), a["run_key"])
        return sorted(rec["files"]), sorted(rec.get("pruned", [])), a
    (static,) = first.statics
    def shown(a):      # the frames the report shows, kept by the metrics record as it shows them
        rec = store.done(Path(a["metrics_folder"]), a["metrics_key"])
        return sorted(n for n in rec["files"] if n.startswith("shown_"))
    kept, pruned, a = files(static, "taa_baseline")
    assert kept == [] and pruned == ["frame_0001.exr", "frame_0004.exr", "frame_0016.exr"]
    assert shown(a) == ["shown_0016.png"]                                          # the one view
    cold = first.ghosts["ghosting"][0]
    kept, pruned, a = files(cold, "taa_baseline")
    show = shown_frames(list(range(26)))
    assert len(show) == 24 and show[0] == 0 and show[-1] == 25
    assert kept == [] and len(pruned) == 26 and shown(a) == [f"shown_{f:04d}.png" for f in show]
    first_cold = cold.per_frame["taa_baseline"]
    assert len(first_cold) == 26                                                # every frame judged

    again = run()                  # nothing to do: the metrics are complete, the pruned runs stay so
    assert again.stats["runs_computed"] == 0 and again.stats["metrics_computed"] == 0

    # the metrics of the cold ghosting run lost (as a change of metric code would): its run is re-made,
    # judged to the same figures and pruned again
    _, _, a = files(cold, "taa_baseline")
    (Path(a["metrics_folder"]) / "done.json").unlink()
    third = run()
    assert third.stats["runs_computed"] == 1 and third.stats["metrics_computed"] == 1
    assert third.ghosts["ghosting"][0].per_frame["taa_baseline"] == first_cold
    assert files(third.ghosts["ghosting"][0], "taa_baseline")[1] == pruned


def test_under_the_figures_rule_a_run_is_made_once_over_every_round_and_pruned_once_settled(tmp_path, reference_pool,
                                                                                             no_plots):
    """A test going to a finer bound is judged again from its runs kept whole, not re-made (each
    round re-made every pruned run: 7 run tasks here instead of 4); once settled they are pruned."""
    from study.config.profile import get_profile
    from study_fixtures import run_tiny_study, summary
    reference_pool.seed(tmp_path / "cache")       # references an earlier test rendered: cache hits
    s = summary(run_tiny_study(tmp_path, "taa_baseline", "noaa", precision="figures"))
    reference_pool.keep(tmp_path / "cache")
    assert s["tasks"]["reference"] > 2 * 5            # more than the probe round: finer bounds were asked
    # one run task per test (static x 2 scenes, cold, warm TAA), each of its runs made once
    assert s["tasks"]["run"] == 4 and s["runs_computed"] == 2 * 2 + 2 + 1
    for done in (tmp_path / "cache" / "runs" / "static").glob("*/*/done.json"):
        rec = json.loads(done.read_text())
        names = {n for n in rec["files"] if n.startswith("frame_")}
        # the TAA keeps the frames of its static views, No AA its one frame
        assert len(names) <= 2 and len(rec.get("pruned", [])) in (0, len(get_profile("quick").static.checkpoints) - 2)
        assert all((done.parent / n).exists() for n in names)
        assert not any((done.parent / n).exists() for n in rec.get("pruned", []))


def test_a_test_judged_again_takes_the_figures_of_frames_whose_references_did_not_change(tmp_path, monkeypatch,
                                                                                         reference_pool):
    """Under the figures' rule a ghosting test is judged again each round some of its instants are
    refined; a frame whose reference and display transform are the ones an earlier round judged it
    against keeps its figures (study.engine.judge.FrameFigures). Every figure, uncertainty, drift
    and decision is the one judging every frame afresh gives, and exactly the frames of unchanged
    instants were taken (each judged once per reference: the number of all_metrics_against calls)."""
    from study.config.profile import get_profile
    from study.config.techniques import TechniqueConfig
    from study.engine import judge as J
    from study.engine.runner import Study
    from study.metrics import judging as M
    scenes = write_scenes(tmp_path)[:1]
    configs = [TechniqueConfig.parse(s) for s in ("taa_baseline", "noaa")]
    calls, logs = [], []
    real = M.all_metrics_against
    monkeypatch.setattr(M, "all_metrics_against", lambda *a, **k: calls.append(1) or real(*a, **k))

    def study(cache):
        calls.clear()
        logs.clear()
        s = Study(quick_every_frame(), cache_root=tmp_path / cache, progress=False, log=logs.append)
        res = s.run(scenes, configs, agreement=False)
        figs = {(t.scene, t.test): (t.per_frame, t.uncertainty, t.temporal, t.temporal_u)
                for t in res.statics + [g for gs in res.ghosts.values() for g in gs]}
        return res, figs, s.drifts, len(calls), list(logs)
    reference_pool.seed(tmp_path / "kept")
    kept, figs, drifts, n, log = study("kept")
    reference_pool.keep(tmp_path / "kept")
    reused = sum(int(m.split("; ")[-1].split()[0]) for m in log if "taken from an earlier round's" in m)
    # the second study starts with the first one's references (content-keyed cache hits): what it
    # checks is the judging, and rendering the same references again was half of this test's time
    shutil.copytree(tmp_path / "kept" / "references", tmp_path / "fresh" / "references")
    get = J.FrameFigures.get
    monkeypatch.setattr(J.FrameFigures, "get", lambda self, *a: None)   # every frame judged afresh
    fresh, figs0, drifts0, n0, _ = study("fresh")
    assert figs == figs0 and drifts == drifts0 and kept.precision == fresh.precision
    assert reused > 0 and n == n0 - reused, (reused, n, n0)
    # a frame's figures are keyed by both references: another display transform is judged afresh
    monkeypatch.setattr(J.FrameFigures, "get", get)
    ff = J.FrameFigures.__new__(J.FrameFigures)
    ff.old, ff.reused = {"3 ref disp": {"": {"mse": 1.0}}}, 0
    assert ff.get(3, "ref", "disp") == {"": {"mse": 1.0}} and ff.get(3, "ref", "other") is None
    assert ff.get(4, "ref", "disp") is None and ff.reused == 1

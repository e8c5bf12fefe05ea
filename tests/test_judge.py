"""study.judge: a test's techniques judged together, each reference read once, the same figures as
judging each run alone (metrics.judge_run, the whole-sequence form)."""
import functools
import json
import math
from pathlib import Path

import numpy as np
import pytest

from study_fixtures import write_scenes
from test_estimate import STUDY


def test_one_metrics_task_per_test_reads_each_reference_once_and_agrees_with_judge_run(tmp_path, monkeypatch):
    from display import DisplayTransform
    from references import cache as rc
    from study import metrics as M
    from study.config import TechniqueConfig, get_profile
    from study.run import Study
    from study.store import Store

    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    scenes = write_scenes(tmp_path)
    path = tmp_path / "units.toml"
    path.write_text(STUDY.format(scenes=json.dumps(scenes)))
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
            disp = {t: DisplayTransform.from_reference(r.image) for t, r in refs.items()}
            ref8 = {t: disp[t].to_8bit(refs[t].image) for t in refs}
            want, _ = M.judge_run(images, run["output_space"], refs, disp, ref8, sorted(images))
            for f in images:
                for k, v in want["per_frame"][str(f)].items():
                    got = test.per_frame[label][f][k]
                    assert (got is None and v is None) or got == pytest.approx(v, rel=1e-12, abs=1e-12), (proto, label, f, k)
            if len(images) > 1:
                assert test.temporal[label] == pytest.approx(want["temporal"], rel=1e-12)
                assert math.isfinite(test.temporal[label]) and test.temporal[label] > 0


def study_scene(spec):
    from study.tasks import load_scene
    return load_scene(spec)

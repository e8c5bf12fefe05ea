"""The disk a study's plan needs, and the runs it keeps whole only while they fit (study.engine.disk)."""
from pathlib import Path

import pytest

from study.engine import disk as D

GB = 2 ** 30


def test_fit_keeps_the_cheapest_runs_whole_while_they_fit_and_prunes_the_rest():
    need = {"references": 3 * GB, "maps": 1 * GB,
            "tests": {("a", "static"): (2 * GB, 1 * GB), ("b", "ghosting"): (10 * GB, 1 * GB),
                      ("c", "ghosting"): (5 * GB, 1 * GB)}, "run": 9 * GB}
    # floor: references 3 + maps 1 + kept 3 + margin 2 + 4 in flight x the largest run's pruned-away 9 = 45 GB
    floor = (3 + 1 + 3 + 2 + 4 * 9) * GB
    logs = []
    assert D.fit(need, floor + 14 * GB, True, Path("/c"), log=logs.append) == frozenset()      # 1 + 9 + 4 fit
    assert D.fit(need, floor + 13 * GB, True, Path("/c"), log=logs.append) == {("b", "ghosting")}
    assert "1 of 3 tests' runs (9.0 GB whole)" in logs[-1]
    assert D.fit(need, floor + 4 * GB, True, Path("/c"), log=logs.append) == {("b", "ghosting"), ("c", "ghosting")}
    assert D.fit(need, floor, True, Path("/c"), log=logs.append) == frozenset(need["tests"])
    # a test pruned in an earlier round stays pruned, and its room is not counted twice
    assert D.fit(need, floor + 14 * GB, True, Path("/c"), frozenset({("a", "static")}), logs.append) == {("a", "static")}
    # the per-pixel rule refines nothing: every run is pruned once judged
    assert D.fit(need, 10 ** 15, False, Path("/c"), log=logs.append) == frozenset(need["tests"])
    with pytest.raises(D.DiskError, match=r"about 45\.0 GB in the cache folder /c .* 44\.0 GB is free"):
        D.fit(need, floor - GB, True, Path("/c"), log=logs.append)


def _study(root, scenes, **kw):
    from study.config.profile import get_profile
    from study.config.techniques import TechniqueConfig
    from study.engine.runner import Study
    logs = []
    s = Study(get_profile("quick"), cache_root=root, progress=False, log=logs.append)
    configs = [TechniqueConfig.parse(x) for x in ("taa_baseline", "noaa")]
    return s, configs, logs


@pytest.mark.long(seconds=25)
def test_a_study_short_of_disk_prunes_its_largest_runs_and_makes_them_again_with_the_same_figures(tmp_path, monkeypatch):
    """A plan whose runs do not fit whole is still computed: the largest test's runs are pruned
    once judged and made again when its references are refined; every figure is the same as with
    room to spare. A plan that cannot fit at all stops before computing anything."""
    from study_fixtures import write_scenes
    scenes = write_scenes(tmp_path)
    s, configs, _ = _study(tmp_path / "roomy", scenes)
    roomy = s.run(scenes, configs, agreement=False)
    plan = s.plan(scenes, configs, agreement=False, final=False, prune=frozenset())[0]  # what a cold cache writes
    s2, _, _ = _study(tmp_path / "probe", scenes)
    need = D.needs(s2.plan(scenes, configs, agreement=False, final=False, prune=frozenset())[0])
    assert not plan.tasks and set(need["tests"]) >= {("tiny_moving", "static"), ("tiny_moving", "ghosting")}
    big = max(need["tests"], key=lambda k: need["tests"][k][0] - need["tests"][k][1])
    tests = need["tests"]
    floor = need["references"] + need["maps"] + sum(k for _, k in tests.values()) + D.margin(need) + D.IN_FLIGHT * need["run"]
    room = sum(w - k for w, k in tests.values()) - (tests[big][0] - tests[big][1])   # all but the largest
    monkeypatch.setattr(D, "free_bytes", lambda folder: floor + room)
    s3, _, logs = _study(tmp_path / "short", scenes)
    short = s3.run(scenes, configs, agreement=False)
    assert any(m.startswith("disk: 1 of ") for m in logs), logs
    for a, b in zip(roomy.statics + [g for gs in roomy.ghosts.values() for g in gs],
                    short.statics + [g for gs in short.ghosts.values() for g in gs]):
        assert (a.scene, a.test) == (b.scene, b.test)
        assert a.per_frame == b.per_frame and a.uncertainty == b.uncertainty and a.temporal == b.temporal
    assert short.precision == roomy.precision
    # its runs were pruned once judged and made again for its finer references
    assert short.precision[big[0]][big[1]]["rounds"][1:], short.precision
    assert short.stats["runs_computed"] > roomy.stats["runs_computed"], (short.stats, roomy.stats)
    # nothing fits: a named error before any task (no reference rendered)
    monkeypatch.setattr(D, "free_bytes", lambda folder: floor - 1)
    s4, _, _ = _study(tmp_path / "full", scenes)
    with pytest.raises(D.DiskError, match=r"the study needs about .* [KMG]B in the cache folder .*full"):
        s4.run(scenes, configs, agreement=False)
    assert not list((tmp_path / "full").rglob("*.exr"))

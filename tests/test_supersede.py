"""Superseded references and metrics records removed as the precision loop refines
(`keep_superseded = false`, study.engine.supersede): the same figures as a study that keeps them,
what another instant or the display still reads kept, and a study killed after a removal resumes
at its finer bounds without rendering a removed reference again."""
import shutil
from dataclasses import replace

import pytest

from references.exr import read_exr
from study_fixtures import quick_every_frame, write_scenes


def _study(root, keep: bool):
    from study.config.profile import get_profile
    from study.config.techniques import TechniqueConfig
    from study.engine.runner import Study
    logs = []
    s = Study(replace(quick_every_frame(), keep_superseded=keep), cache_root=root, progress=False, log=logs.append)
    return s, [TechniqueConfig.parse("taa_baseline")], logs


def _refs(root) -> dict:
    """reference file name -> its bound (LSB)."""
    return {p.name: float(read_exr(p)[0]["taa_bound_lsb"]) for p in (root / "references").rglob("*.exr")
            if not p.name.endswith(".extremes.exr")}


def _figures(res) -> list:
    tests = res.statics + [g for gs in res.ghosts.values() for g in gs]
    return [(t.scene, t.test, t.per_frame, t.uncertainty, t.temporal) for t in tests]


def _seed(root, cache):
    """Start `cache` with every reference the study that keeps them rendered (cache hits: what is
    superseded is removed wherever it came from)."""
    shutil.copytree(root / "kept" / "references", cache / "references")


@pytest.fixture(scope="module")
def studies(tmp_path_factory, reference_pool):
    """The tiny moving scene studied keeping and removing what is superseded (3 rounds: 8 LSB, then
    0.25 and 0.125 at its ghosting instants, then one more instant at 0.125)."""
    root = tmp_path_factory.mktemp("supersede")
    scenes = write_scenes(root)[:1]
    out = {}
    for name, keep in (("kept", True), ("removed", False)):
        if keep:
            reference_pool.seed(root / name)
        else:
            _seed(root, root / name)
        s, configs, logs = _study(root / name, keep)
        out[name] = (s.run(scenes, configs, agreement=False), logs)
        if keep:
            reference_pool.keep(root / name)
    return root, scenes, out


@pytest.mark.long(seconds=12)
def test_a_refined_instants_coarser_reference_is_removed_and_the_figures_are_those_kept(studies):
    root, _, out = studies
    (kept, _), (removed, logs) = out["kept"], out["removed"]
    assert _figures(removed) == _figures(kept) and removed.precision == kept.precision
    assert len(kept.precision["tiny_moving"]["ghosting"]["rounds"]) >= 2, kept.precision
    a, b = _refs(root / "kept"), _refs(root / "removed")
    gone = {n: bound for n, bound in a.items() if n not in b}
    assert set(b) < set(a) and gone, (a, b)
    # what went is a bound refined past: the probe's (its display transforms kept as records) or an
    # intermediate one, not a final one
    finals = {float(x) for p in kept.precision["tiny_moving"].values() for x in p["bounds"]}
    assert all(bound not in finals or bound == 0.25 for bound in gone.values()), gone
    assert 8.0 in gone.values() and any(b < 8.0 for b in gone.values()), gone
    assert any(m.startswith("disk: ") and "superseded removed" in m for m in logs), logs
    # metrics records judged against a removed reference went too; nothing is left in the trash
    n = lambda r: len(list((r / "metrics").rglob("done.json")))    # noqa: E731
    assert n(root / "removed") < n(root / "kept")
    assert not (root / "removed" / "trash").exists()


@pytest.mark.long(seconds=1)
def test_a_removed_probe_leaves_its_display_transform_and_is_never_rendered_again(studies):
    """The probe's references at 8 LSB are the display's (each frame's display transform, the
    display-space runs' key). Refined past, each is removed with the rest, its transform kept as
    its record (references.cache); a probe an unrefined instant still judges against stays. Nothing
    was rendered: every display transform was read from a record, and each equals the one its
    reference gives."""
    from references.cache import display_path, read_display
    from display import DisplayTransform
    root, _, out = studies
    a, b = _refs(root / "kept"), _refs(root / "removed")
    probe = {n for n, bound in a.items() if bound == 8.0}
    gone = probe - set(b)
    assert gone, (probe, b)
    for name in probe:
        path = next((root / "removed" / "references").rglob(name.replace(".exr", ".display.json"))).with_name(name)
        kept_path = next((root / "kept" / "references").rglob(name))
        got = read_display(path, path.stem)
        assert got == DisplayTransform.from_reference(
            __import__("numpy").stack([read_exr(kept_path)[1][c] for c in "RGB"], -1)), name
        assert display_path(path).exists() and (path.exists() == (name not in gone))
    assert out["removed"][0].stats["references_rendered"] == 0     # each read where it was seeded


@pytest.mark.long(seconds=6)
@pytest.mark.parametrize("removed_first", [True, False], ids=["after-the-removal", "before-it"])
def test_a_killed_study_resumes_at_its_finer_bounds(studies, tmp_path, monkeypatch, removed_first):
    """Killed as its third round starts, after removing what the second read (or before): the same
    command resumes at the third round's bounds, renders nothing removed, removes what is left."""
    from study.engine import supersede as S
    root, scenes, out = studies
    real, calls = S.before_round, []

    def killed(study, before, now):
        calls.append(1)
        if len(calls) == 3 and not removed_first:
            raise KeyboardInterrupt
        got = real(study, before, now)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return got
    monkeypatch.setattr(S, "before_round", killed)
    _seed(root, tmp_path)
    s, configs, _ = _study(tmp_path, keep=False)
    with pytest.raises(KeyboardInterrupt):
        s.run(scenes, configs, agreement=False)
    monkeypatch.setattr(S, "before_round", real)
    removed_then = set(_refs(tmp_path))
    s, configs, logs = _study(tmp_path, keep=False)
    res = s.run(scenes, configs, agreement=False)
    assert res.stats["references_rendered"] == 0, res.stats
    assert any(m.startswith("precision: resuming") for m in logs), logs
    assert _figures(res) == _figures(out["kept"][0]) and res.precision == out["kept"][0].precision
    # no removed reference was rendered again: the resumed study's are the uninterrupted one's
    # and what the killed round had not removed yet is removed on resuming
    assert set(_refs(tmp_path)) == set(_refs(root / "removed"))
    assert (removed_then <= set(_refs(tmp_path))) == removed_first
    assert not list((tmp_path / "precision" / "progress").rglob("*.json"))      # finished: nothing to resume


def test_the_disk_plan_holds_over_every_round_where_superseded_artefacts_are_removed(tmp_path):
    """study.engine.disk: removing what a finer bound supersedes (the probe's references too, their
    display transforms kept as records) before the finer round renders, the peak is one round's
    files, and `estimate` says what it assumes; a disk that does not hold one round is refused."""
    from study.engine import disk as D
    mb = 2 ** 20
    need = {"references": 40 * mb, "maps": 10 * mb, "tests": {("s", "ghosting"): (300 * mb, 5 * mb)}, "run": 0}
    first = 40 * mb + 10 * mb + 5 * mb + D.margin(need)          # references, maps, shown frames, margin
    kept, removed = D.summary(need, 10 ** 12, True, False), D.summary(need, 10 ** 12, True, True)
    assert kept["planned_gb"] * 2 ** 30 == pytest.approx(first) == removed["planned_gb"] * 2 ** 30
    assert "hold over every round" in D.describe(removed)[-1] and "display transform" in D.describe(removed)[-1]
    assert "the first round only" in D.describe(kept)[-1]
    D.fit(need, first, False, tmp_path)
    with pytest.raises(D.DiskError, match=r"references 40.0 MB"):
        D.fit(need, first - mb, False, tmp_path)
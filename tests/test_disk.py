"""The disk a study's plan needs, and the runs it keeps whole only while they fit (study.engine.disk)."""
import shutil
from pathlib import Path

import numpy as np
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


def test_fit_keeps_runs_whole_within_the_disk_budget_and_a_small_budget_prunes_without_error():
    need = {"references": 3 * GB, "maps": 1 * GB,
            "tests": {("a", "static"): (2 * GB, 1 * GB), ("b", "ghosting"): (10 * GB, 1 * GB),
                      ("c", "ghosting"): (5 * GB, 1 * GB)}, "run": 9 * GB}
    floor, spare = (3 + 1 + 3 + 2 + 4 * 9) * GB, 2 * GB
    logs = []
    # the disk has room for all three whole (14 GB over the floor); the budget leaves 5 GB over what
    # the cache must hold (its margin is the disk's, not the cache's): a (1) and c (4) whole, b pruned
    assert D.fit(need, floor + 14 * GB, True, Path("/c"), log=logs.append,
                 budget=floor - spare + 5 * GB) == {("b", "ghosting")}
    assert "the disk budget leaves" in logs[-1]
    assert D.fit(need, floor + 14 * GB, True, Path("/c"), log=logs.append,
                 budget=floor - spare + 4 * GB) == {("b", "ghosting"), ("c", "ghosting")}     # a alone
    # the free disk binds before a larger budget does
    assert D.fit(need, floor + 4 * GB, True, Path("/c"), log=logs.append, budget=10 ** 15) == {("b", "ghosting"), ("c", "ghosting")}
    # a budget under what the plan must hold prunes every test; the free disk alone stops a study
    assert D.fit(need, floor + 14 * GB, True, Path("/c"), log=logs.append, budget=GB) == frozenset(need["tests"])
    # estimate's figure: the peak planned is the budget (with its margin) when it binds
    judged_as_made = {**need, "run": 0}   # margin a quarter of 7: least 3 + 1 + 3 + 1.75, peak 3 + 1 + 17 + 1.75
    s = D.summary(judged_as_made, floor, False, True, budget=12 * GB)
    assert (s["least_gb"], s["peak_gb"], s["budget_gb"], s["planned_gb"]) == (8.75, 22.75, 12, 13.75)
    assert "within the profile's disk_budget_gb of 12 GB" in "\n".join(D.describe(s))
    assert D.summary(judged_as_made, floor, False, True, budget=30 * GB)["planned_gb"] == 22.75     # the peak fits


def test_used_bytes_counts_every_file_under_a_folder(tmp_path):
    (tmp_path / "a" / "b").mkdir(parents=True)
    (tmp_path / "a" / "x.bin").write_bytes(b"1" * 1000)
    (tmp_path / "a" / "b" / "y.bin").write_bytes(b"2" * 24)
    assert D.used_bytes(tmp_path) == 1024
    assert D.used_bytes(tmp_path / "missing") == 0


EDGES = np.array([0.0, -0.0, 1.0, -1.0, np.nextafter(np.float32(1), np.float32(2)), 1e-45, -1e-45,
                  np.finfo(np.float32).tiny, np.finfo(np.float32).smallest_subnormal * 3, np.finfo(np.float32).max,
                  -np.finfo(np.float32).max, np.finfo(np.float32).eps, 65504.0, 65505.0, 6e-8, 3.1e38], np.float32)


def _same_bits(a, b):
    return np.array_equal(np.ascontiguousarray(a, np.float32).view(np.uint32),
                          np.ascontiguousarray(b, np.float32).view(np.uint32))


def test_kept_files_round_trip_bit_for_bit_in_each_lossless_codec(tmp_path):
    """Every codec a kept file is written with returns each float32 bit for bit: the edge values
    (signed zeros, subnormals, the largest floats, halves' overflow) and noise; a codec that is not
    lossless is refused by name."""
    from references.exr import ExrError, read_exr, write_exr
    from study.engine.store import Store, codec
    rng = np.random.default_rng(3)
    noise = (rng.standard_normal((27, 48, 3)) * rng.lognormal(0, 8, (27, 48, 3))).astype(np.float32)
    noise.reshape(-1)[:EDGES.size] = EDGES
    for name in ("zip", "zstd"):
        write_exr(tmp_path / f"{name}.exr", {"RGB": noise, "flip_ldr": noise[..., 0]}, compression=name)
        _, ch = read_exr(tmp_path / f"{name}.exr")
        assert all(_same_bits(ch[c], noise[..., k]) for k, c in enumerate("RGB")) and _same_bits(ch["flip_ldr"], noise[..., 0])
    with pytest.raises(ExrError, match=r"bad\.exr: compression must be one of \['zip', 'zstd', 'smallest'\] .*'pxr24'"):
        write_exr(tmp_path / "bad.exr", {"RGB": noise}, compression="pxr24")
    assert not (tmp_path / "bad.exr").exists()
    # a folder's maps are Zstandard, its frames ZIP; both read back as written, and maps are smaller
    assert (codec("maps_0016.exr"), codec("frame_0016.exr")) == ("zstd", "zip")
    st = Store(tmp_path / "c")
    smooth = np.linspace(0, 1, 48 * 27, dtype=np.float32).reshape(27, 48) ** 2.2
    rec = st.save_folder(tmp_path / "c" / "f", "k", {"maps_0001.exr": {"ssim": smooth, "flip_ldr": noise[..., 1]},
                                                      "frame_0001.exr": noise}, {})
    got = st.read_image(tmp_path / "c" / "f", "maps_0001.exr", rec)
    assert _same_bits(got["ssim"], smooth) and _same_bits(got["flip_ldr"], noise[..., 1])
    assert _same_bits(np.stack([st.read_image(tmp_path / "c" / "f", "frame_0001.exr", rec)[c] for c in "RGB"], -1), noise)


def test_a_cached_reference_keeps_its_halves_bit_for_bit_and_its_extremes_beside_it_only_for_reuse(tmp_path):
    """The reference cache stores the image, standard errors, floor and halves exactly; a
    reference's sample extremes (what the next frame's reuse reads, nothing else) only when
    rendered for reuse, in a file beside it (`<key>.extremes.exr`, 6 of 22 channels, the noisiest:
    deleted once the next frame is made); its display transform in a record beside it, read
    without the reference."""
    from types import SimpleNamespace

    from display import DisplayTransform
    from references.cache import ReferenceCache, display_path, extremes_path, read_display
    from references.exr import read_exr
    from references.result import Reference
    rng = np.random.default_rng(5)

    def img():
        x = rng.lognormal(0, 3, (27, 48, 3)).astype(np.float32)
        x.reshape(-1)[:EDGES.size] = np.abs(EDGES)
        return x
    ref = Reference(img(), img(), 64, 2, 1.5, 61.0, "k" * 24, spp_map=rng.integers(2, 4096, (27, 48)).astype(np.int32),
                    display_stderr=np.minimum(img(), 1), display_floor=np.minimum(img(), 1), half_delta=img() - img(), sample_lo=img(), sample_hi=img())
    cache = ReferenceCache(tmp_path)
    scene = SimpleNamespace(name="s", content_hash="h")
    for reuse in (False, True):
        path = tmp_path / f"{reuse}.exr"
        cache._write(path, ref, scene, 0, extremes=reuse)
        back = cache._read(path, ref.key, (27, 48, 3))
        for f in ("image", "stderr", "display_stderr", "display_floor", "half_delta"):
            assert _same_bits(getattr(back, f), getattr(ref, f)), f
        for half, want in zip(back.halves(), ref.halves()):
            assert _same_bits(half, want)
        assert np.array_equal(back.spp_map, ref.spp_map)
        assert "sample_lo.R" not in read_exr(path)[1] and extremes_path(path).exists() is reuse
        assert (back.sample_lo is not None) is reuse
        if reuse:
            assert _same_bits(back.sample_lo, ref.sample_lo) and _same_bits(back.sample_hi, ref.sample_hi)
            extremes_path(path).unlink()          # as once the next frame is made: no longer a source
            assert cache._read(path, ref.key, (27, 48, 3)).sample_lo is None
        assert read_display(path, ref.key) == DisplayTransform.from_reference(ref.image)
        assert read_display(path, "other" * 4) is None          # a record of another key is not read
    display_path(path).write_text('{"taa_key": "%s", "log_average": NaN, "white": 1, "key": 0.18}' % ref.key)
    assert read_display(path, ref.key) is None                  # nor a record with a NaN


def _real_bytes(root):
    """(bytes on disk, what study.engine.disk.file_bytes allows) of each kind of file under a cache."""
    from references.exr import read_exr
    out = {}
    for kind, glob in (("reference", "references/**/*.exr"), ("frame", "runs/**/frame_*.exr"),
                       ("maps", "metrics/**/maps_*.exr")):
        real = allowed = 0
        for f in Path(root).glob(glob):
            ch = read_exr(f)[1]
            h, w = next(iter(ch.values())).shape[:2]
            real += f.stat().st_size
            allowed += D.file_bytes("extremes" if f.name.endswith(".extremes.exr") else kind, w, h)
        out[kind] = (real, allowed)
    return out


def _study(root, scenes, **kw):
    from study.config.profile import get_profile
    from study.config.techniques import TechniqueConfig
    from study.engine.runner import Study
    from dataclasses import replace
    logs = []
    s = Study(replace(get_profile("quick"), **kw), cache_root=root, progress=False, log=logs.append)
    configs = [TechniqueConfig.parse(x) for x in ("taa_baseline", "noaa")]
    return s, configs, logs


@pytest.mark.long(seconds=35)
def test_a_study_short_of_disk_prunes_its_largest_runs_and_makes_them_again_with_the_same_figures(tmp_path, monkeypatch,
                                                                                                  reference_pool):
    """A plan whose runs do not fit whole is still computed: the largest test's runs are pruned
    once judged and made again when its references are refined; every figure is the same as with
    room to spare. A plan that cannot fit at all stops before computing anything."""
    from study_fixtures import write_scenes
    scenes = write_scenes(tmp_path)
    s, configs, _ = _study(tmp_path / "roomy", scenes)
    reference_pool.seed(tmp_path / "roomy")      # references an earlier test rendered: cache hits
    roomy = s.run(scenes, configs, agreement=False)
    reference_pool.keep(tmp_path / "roomy")
    # the disk the estimate allows each file is no less than what the study's real files take
    for kind, (real, allowed) in _real_bytes(tmp_path / "roomy").items():
        assert 0 < real <= allowed, (kind, real, allowed)
    plan = s.plan(scenes, configs, agreement=False, final=False, prune=frozenset())[0]  # what a cold cache writes
    s2, _, _ = _study(tmp_path / "probe", scenes)
    need = D.needs(s2.plan(scenes, configs, agreement=False, final=False, prune=frozenset())[0])
    assert not plan.tasks and set(need["tests"]) >= {("tiny_moving", "static"), ("tiny_moving", "ghosting")}
    big = max(need["tests"], key=lambda k: need["tests"][k][0] - need["tests"][k][1])
    tests = need["tests"]
    floor = need["references"] + need["maps"] + sum(k for _, k in tests.values()) + D.margin(need) + D.IN_FLIGHT * need["run"]
    room = sum(w - k for w, k in tests.values()) - (tests[big][0] - tests[big][1])   # all but the largest
    # The next two studies start with the references the roomy one rendered (content-keyed files,
    # found as cache hits): what they prove is about their runs, and rendering the same references
    # twice more was most of this test's time. Cached references need no disk, so neither does the floor.
    assert need["references"] > 0
    for name in ("short", "lean"):
        shutil.copytree(tmp_path / "roomy" / "references", tmp_path / name / "references")
    monkeypatch.setattr(D, "free_bytes", lambda folder: floor - need["references"] + room)
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
    assert short.stats["references_rendered"] == 0, short.stats
    # the profile's lean policy (the thesis's): every test's runs pruned once judged, whatever the disk,
    # made again when refined; the same figures, and the report still reads every frame it shows
    from study.engine.plan import shown_frames
    from study.engine.results import Artefacts
    s5, _, _ = _study(tmp_path / "lean", scenes, runs_while_refining="pruned")
    lean = s5.run(scenes, configs, agreement=False)
    for a, b in zip(roomy.statics + [g for gs in roomy.ghosts.values() for g in gs],
                    lean.statics + [g for gs in lean.ghosts.values() for g in gs]):
        assert a.per_frame == b.per_frame and a.uncertainty == b.uncertainty and a.temporal == b.temporal
    assert lean.precision == roomy.precision
    assert lean.stats["runs_computed"] > short.stats["runs_computed"], (lean.stats, short.stats)
    art = Artefacts(tmp_path / "lean")
    for res in lean.statics:
        for a in res.artefacts.values():
            assert all(art.frame_8bit(a, f, None).shape == (res.height, res.width, 3) for f in a["maps_for"])
    for g in (g for gs in lean.ghosts.values() for g in gs):
        for a in g.artefacts.values():
            assert all(art.frame_8bit(a, t, None).shape == (g.height, g.width, 3) for t in shown_frames(g.frames))
    # nothing fits: a named error before any task (no reference rendered)
    monkeypatch.setattr(D, "free_bytes", lambda folder: floor - 1)
    s4, _, _ = _study(tmp_path / "full", scenes)
    with pytest.raises(D.DiskError, match=r"the study needs about .* [KMG]B in the cache folder .*full"):
        s4.run(scenes, configs, agreement=False)
    assert not list((tmp_path / "full").rglob("*.exr"))


def test_run_stops_first_with_status_2_and_one_line_when_the_disk_cannot_hold_the_plan(tmp_path, monkeypatch):
    """The CLI's `run`: exit 2 before any task, one line naming the GB needed, the GB free and the
    cache folder; nothing written."""
    from study_fixtures import run_cli, write_scenes
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(D, "free_bytes", lambda folder: 5 * 2 ** 20)
    scenes = write_scenes(tmp_path)
    r = run_cli(["run", "--scenes", ",".join(scenes), "--no-agreement", "--out", tmp_path / "out",
                 "--techniques", "noaa"], code=2)
    lines = [x for x in r.output.splitlines() if "needs about" in x]
    assert len(lines) == 1 and "Traceback" not in r.output, r.output
    assert f"in the cache folder {tmp_path / 'cache'}" in lines[0] and "and 5.0 MB is free" in lines[0], lines[0]
    assert not list(tmp_path.rglob("*.exr"))


def test_budget_left_is_the_budget_less_what_the_cache_holds_plus_what_is_about_to_go(tmp_path):
    (tmp_path / "x.bin").write_bytes(b"0" * 4096)
    assert D.budget_left(None, tmp_path) is None
    assert D.budget_left(1.0, tmp_path) == GB - 4096
    assert D.budget_left(1.0, tmp_path, freed=4096) == GB

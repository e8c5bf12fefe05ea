"""What a judged test keeps on disk (study.engine.disk, study.engine.judge): the frames the report
shows as the 8-bit images it shows, no float frame of a pruned run, references in the smaller
lossless codec, and an estimate that is what the cache then holds."""
import json
from pathlib import Path

import numpy as np
import OpenEXR

from test_estimate import STUDY


def test_smallest_codec_keeps_the_smaller_file_bit_for_bit(tmp_path):
    """'smallest' writes ZIP and Zstandard and keeps the smaller: Zstandard for noise, ZIP for a
    smooth ramp here (as for sphere_ghosting's references and a smooth scene's), the same bits."""
    from references.exr import read_exr, write_exr
    rng = np.random.default_rng(1)
    noise = (rng.lognormal(0, 1, (64, 96, 3)) * 1e-3).astype(np.float32)
    ramp = np.broadcast_to(np.linspace(0, 1, 96, dtype=np.float32)[None, :, None], (64, 96, 3))
    for name, img, want in (("noise", noise, OpenEXR.ZSTD_COMPRESSION), ("ramp", ramp, OpenEXR.ZIP_COMPRESSION)):
        sizes = {}
        for codec in ("zip", "zstd", "smallest"):
            write_exr(tmp_path / f"{name}_{codec}.exr", {"RGB": img}, {"taa_key": "k"}, compression=codec)
            sizes[codec] = (tmp_path / f"{name}_{codec}.exr").stat().st_size
        assert sizes["smallest"] == min(sizes["zip"], sizes["zstd"]) < max(sizes["zip"], sizes["zstd"]), sizes
        h, ch = read_exr(tmp_path / f"{name}_smallest.exr")
        assert h["compression"] == want and h["taa_key"] == "k"
        assert np.array_equal(np.stack([ch[c] for c in "RGB"], -1).view(np.uint32), np.asarray(img).view(np.uint32))
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.endswith(".part")) == []   # no temporary left


def test_a_pruned_run_keeps_no_float_frame_and_the_report_reads_its_shown_frames_as_judged(tmp_path, monkeypatch):
    """Judged with its runs kept whole, then judged again pruned: the metrics record holds the
    report's shown frames as PNGs, each the 8-bit image the float frame gives under the frame's
    display transform, and the run no float frame at all."""
    from study.config.profile import get_profile
    from study.config.techniques import TechniqueConfig
    from study.engine.plan import shown_frames
    from study.engine.runner import Study
    from study.engine.store import Store
    from study_fixtures import moving_scene

    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    scene = tmp_path / "long.toml"
    scene.write_text(moving_scene(frames=28, size=(24, 16)))
    text = STUDY.format(scenes=json.dumps([str(scene)])).replace("frames = 4", "frames = 28")
    configs = [TechniqueConfig.parse(s) for s in ("taa_baseline", "noaa")]

    def run(keep_all: bool):
        path = tmp_path / "s.toml"
        path.write_text(text.replace("sweep = false\n", 'sweep = false\nkeep_frames = "all"\n') if keep_all else text)
        study = Study(get_profile(str(path)), cache_root=tmp_path / "cache", progress=False)
        return study.run([str(scene)], configs, agreement=False)
    whole = run(keep_all=True)
    store = Store(tmp_path / "cache")
    cold = whole.ghosts["ghosting"][0]
    a = cold.artefacts["taa_baseline"]
    show = shown_frames(cold.frames)
    assert len(show) == 24 and len(cold.frames) == 28
    # the float frames through each frame's display transform (the report's images until now)
    want = {t: whole.artefacts.frame_8bit(a, t, whole.display(cold.scene, t, cold.width, cold.height)) for t in show}
    assert all(w.dtype == np.uint8 and w.shape == (16, 24, 3) for w in want.values())
    (Path(a["metrics_folder"]) / "done.json").unlink()          # judged again, now pruned once judged
    pruned = run(keep_all=False)
    assert pruned.stats["runs_computed"] == 0 and pruned.stats["metrics_computed"] == 1
    assert pruned.ghosts["ghosting"][0].per_frame["taa_baseline"] == cold.per_frame["taa_baseline"]
    run_rec = store.done(Path(a["folder"]), a["run_key"])
    assert run_rec["files"] == {} and len(run_rec["pruned"]) == 28
    assert not list(Path(a["folder"]).glob("frame_*.exr"))
    m = store.done(Path(a["metrics_folder"]), a["metrics_key"])
    assert sorted(n for n in m["files"] if n.startswith("shown_")) == [f"shown_{t:04d}.png" for t in show]
    for t in show:
        got = pruned.artefacts.frame_8bit(a, t, None)          # read back: no float frame, no transform
        assert np.array_equal(got, want[t]), t



def test_a_run_pruned_once_judged_is_judged_as_it_is_made_and_never_writes_a_float_frame(tmp_path, monkeypatch):
    """Runs pruned once judged are judged by their run task frame by frame (study.engine.run_task):
    not one float frame is written, their metrics are filed with the shown PNGs, a second study
    computes nothing, and the figures are those of judging the float frames of runs kept whole."""
    from study.config.profile import get_profile
    from study.config.techniques import TechniqueConfig
    from study.engine.runner import Study
    from study.engine.store import FolderWriter
    from study_fixtures import moving_scene

    scene = tmp_path / "moving.toml"
    scene.write_text(moving_scene(frames=8, size=(24, 16)))
    configs = [TechniqueConfig.parse(s) for s in ("taa_baseline", "noaa")]
    written = []
    real = FolderWriter.add
    monkeypatch.setattr(FolderWriter, "add", lambda self, name, data: (written.append(name), real(self, name, data)))

    def run(cache: str, keep_all: bool = False):
        monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / cache))
        text = STUDY.format(scenes=json.dumps([str(scene)]))
        path = tmp_path / "s.toml"
        path.write_text(text.replace("sweep = false\n", 'sweep = false\nkeep_frames = "all"\n') if keep_all else text)
        return Study(get_profile(str(path)), cache_root=tmp_path / cache, progress=False).run(
            [str(scene)], configs, agreement=False)
    streamed = run("a")
    assert streamed.stats["runs_computed"] > 0 and streamed.stats["metrics_computed"] > 0
    assert [n for n in written if n.startswith("frame_")] == [] and any(n.startswith("maps_") for n in written)
    assert list((tmp_path / "a" / "runs").rglob("*.exr")) == []
    assert len(list((tmp_path / "a" / "metrics").rglob("shown_*.png"))) > 0
    written.clear()
    again = run("a")
    assert again.stats["runs_computed"] == again.stats["metrics_computed"] == 0 and written == []
    whole = run("b", keep_all=True)     # every run kept whole: its metrics task judges its float frames
    assert [n for n in written if n.startswith("frame_")]
    tests = lambda r: r.statics + r.ghosts["ghosting"] + r.ghosts["ghosting_warm"]     # noqa: E731
    assert len(tests(streamed)) == 3
    for a, b in zip(tests(streamed), tests(whole)):
        assert a.per_frame == b.per_frame and a.uncertainty == b.uncertainty and a.temporal == b.temporal


def test_the_plan_prices_shown_frames_as_png_and_no_run_in_flight_where_runs_are_judged_as_made():
    """study.engine.disk.needs: a column whose shown frames are kept as PNGs (judged as its run is
    made once pruned) costs its shown frames' PNG bytes once pruned and holds no run in flight; a
    column the video metric reads keeps float frames and is whole until judged; a reference costs
    its scene's measured bytes a pixel."""
    from types import SimpleNamespace as NS

    from study.engine import disk as D
    w, h = 1600, 900
    frames = {f: f for f in range(100)}
    test = NS(scene="sphere_ghosting", protocol=NS(name="ghosting"), width=w, height=h,
              run_keys={"taa": "r1", "vdp": "r2"}, frame_times={"taa": frames, "vdp": frames},
              keep={"taa": list(range(0, 100, 4)), "vdp": list(range(0, 100, 4))},
              maps_for={"taa": [], "vdp": [99]}, metrics_keys={"taa": "m1", "vdp": "m2"})
    run = NS(kind="run", spec=NS(keys={"taa": "r1", "vdp": "r2"}))
    metrics = NS(kind="metrics", spec=NS(items=[{"key": "m1", "shown_8bit": True}, {"key": "m2", "shown_8bit": False}]))
    refs = [NS(kind="reference", likely_cached=False, spec=NS(width=w, height=h, settings={}, scene=s))
            for s in ("sphere_ghosting", "hairball_rotating_unlit", "a_scene_never_measured")]
    need = D.needs(NS(tasks={"a": run, "b": metrics, **{f"ref{i}": r for i, r in enumerate(refs)}}, tests=[test]))
    px, f = w * h, D.FILE_BYTES
    assert need["references"] == px * (24 + 12 + D.REFERENCE_BYTES) + 3 * f
    whole, kept = need["tests"][("sphere_ghosting", "ghosting")]
    assert whole == 2 * 100 * (px * D.FRAME_BYTES + f)
    assert kept == 25 * (px * D.SHOWN_BYTES + f) + 25 * (px * D.FRAME_BYTES + f)
    assert need["run"] == 75 * (px * D.FRAME_BYTES + f)             # the video column's, pruned once judged
    assert need["maps"] == px * D.MAPS_BYTES + f

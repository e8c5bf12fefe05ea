"""study.engine.estimate: the work units a plan implies, counted by hand for a tiny study."""
import json

from study_fixtures import run_cli, write_scenes

STUDY = """
name = "units"
scenes = {scenes}
resolution = "quick"
agreement = false
sweep = false
ghosting_skip = []
[[techniques]]
spec = "taa_baseline"
[[techniques]]
spec = "noaa"
[[techniques]]
label = "SSAA 4x"
technique = "accumulation"
params = {{ samples = 4 }}
[protocols.static]
history = 16
checkpoints = [1, 4, 16]
thesis_history = 16
[[protocols.ghosting]]
name = "ghosting"
frames = 4
warmup = 0
[[protocols.ghosting]]
name = "ghosting_warm"
frames = 4
warmup = 16
[video]
metric = "none"
[precision]
rule = "per_pixel"
"""


def _estimate(path):
    return {r["scene"]: r for r in json.loads(run_cli(["estimate", path, "--json"]).output)["scenes"]}


def test_units_of_a_tiny_study_by_hand_and_none_once_it_ran(tmp_path, monkeypatch):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    scenes = write_scenes(tmp_path)
    path = tmp_path / "units.toml"
    path.write_text(STUDY.format(scenes=json.dumps(scenes)))
    got = _estimate(path)
    mov, still = got["tiny_moving"], got["tiny_still"]
    # tiny_moving, 4 frames: one reference per frame (the static test's frame 0 is ghosting's t = 0),
    # and its probe, whose display transform every figure of the frame is judged under
    assert mov["references"] == 2 * 4
    # raster frames rendered once each: static 16 jittered + 1 centre; cold ghosting 4 jittered +
    # 4 centre; warm: 16 warm-up at t = 0, then t = 0..3 with jitter 16..19 = 0..3, of which
    # (t 0, jitter 0, previous 0) is the first warm-up frame: 16 + 3 (its No AA is the cold run's)
    assert mov["raster_frames"] == 17 + 8 + 19
    assert mov["subframes"] == 4 * (1 + 4)                   # SSAA 4x: static once, cold ghosting 4
    assert mov["technique_steps"] == (16 + 4 + 20) + (1 + 4) + (1 + 4)
    assert mov["technique_frames_judged"] == (3 + 4 + 4) + (1 + 4) + (1 + 4)
    # every run is pruned once judged under the per-pixel rule: judged as it is made, none written;
    # runs kept whole write every judged frame, read back by their metrics task
    assert mov["technique_frames_written"] == still["technique_frames_written"] == 0
    whole = tmp_path / "whole.toml"
    whole.write_text(STUDY.format(scenes=json.dumps(scenes)).replace('sweep = false', 'sweep = false\nkeep_frames = "all"'))
    assert _estimate(whole)["tiny_moving"]["technique_frames_written"] == mov["technique_frames_judged"]
    # tiny_still is not animated: the static test only
    assert (still["references"], still["raster_frames"], still["subframes"]) == (2, 17, 4)
    assert (still["technique_steps"], still["technique_frames_judged"]) == (16 + 1 + 1, 3 + 1 + 1)
    # its run task holds the 17 frames of its one instant, of the buffers Uncharted reads (colour 12,
    # depth 4, motion 8 bytes a pixel; SSAA's sub-frames are read one at a time, not kept), one render
    # in flight and each of 3 columns' share (study.engine.estimate.run_memory)
    px = still["resolution"][0] * still["resolution"][1]
    assert still["run_memory_bytes"] == 600 * 2 ** 20 + 256 * px + 17 * 24 * px + 3 * 12 * px
    # a moving test keeps one instant's frames (its warm test's 16 warm-up frames at t = 0, not all
    # 19 of its run): tiny_moving's largest run task is its static test's, as tiny_still's
    pm = mov["resolution"][0] * mov["resolution"][1]
    assert mov["run_memory_bytes"] == 600 * 2 ** 20 + 256 * pm + 17 * 24 * pm + 3 * 12 * pm

    run_cli(["run", path, "--out", tmp_path / "out", "--precision", "per_pixel"])
    doc = json.loads(run_cli(["estimate", path, "--json"]).output)
    assert doc["tasks"] == {} and doc["scenes"] == []
    # runs and their figures gone, references kept: their tasks are planned (they read the files)
    # but not counted as work to do
    import shutil
    for d in ("runs", "metrics", "frame-figures"):
        shutil.rmtree(tmp_path / "cache" / d, ignore_errors=True)
    doc = json.loads(run_cli(["estimate", path, "--json"]).output)
    assert doc["tasks"]["reference"] > 0 and "reference" not in doc["to_compute"]
    assert doc["to_compute"]["run"] == doc["tasks"]["run"] > 0 and doc["complete"] >= doc["tasks"]["reference"]
    line = run_cli(["estimate", path]).output.splitlines()[0]
    assert line.startswith("units: tasks to compute {") and "'reference'" not in line, line
    scratch = json.loads(run_cli(["estimate", path, "--json", "--from-scratch"]).output)
    assert {r["scene"]: r for r in scratch["scenes"]} == got          # the whole study's work again


def test_the_buffers_a_kept_frame_holds_are_priced_as_the_raster_makes_them():
    """raster.limits.BUFFER_BYTES, which prices a run task's kept frames, against a render's arrays."""
    from raster import Rasterizer
    from raster.frames import BUFFERS
    from raster.limits import BUFFER_BYTES, frame_bytes
    from study.engine.tasks import load_scene
    r = Rasterizer(load_scene("pipe"), 12, 8)
    try:
        got = r.render(0, (0.0, 0.0), BUFFERS, prev_t=0)
    finally:
        r.close()
    assert {k: v.nbytes // (12 * 8) for k, v in got.items()} == BUFFER_BYTES
    assert frame_bytes(12, 8, ["depth"]) == 12 * 8 * (12 + 4)          # colour is always kept

"""ColorVideoVDP as the study's perceptual video metric (study.metrics.video, study.engine.video_task):
the metric's own invariants, our call against the package's command-line tool, and a real study
whose ghosting and static tables carry a JOD judged against the reference and its halves."""
import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from study_fixtures import run_cli, write_scenes

pytestmark = pytest.mark.long(seconds=60)


@pytest.fixture(scope="module")
def vdp():
    from study.metrics.video import metric
    return metric("standard_fhd", 1)


def _clip(seed=0, frames=12, h=36, w=64):
    return np.random.default_rng(seed).integers(40, 200, (frames, h, w, 3), dtype=np.uint8)


def _shift(a, d):
    return np.clip(a.astype(np.int16) + d, 0, 255).astype(np.uint8)


def test_identical_videos_and_images_score_the_maximum(vdp):
    ref = _clip()
    assert vdp.jod(ref, ref, 60)[0] == pytest.approx(10.0, abs=1e-4)
    assert vdp.jod(ref[3], ref[3], 0)[0] == pytest.approx(10.0, abs=1e-4)


def test_more_flicker_scores_lower(vdp):
    ref = _clip()
    sign = np.where(np.arange(len(ref)) % 2, 1, -1)[:, None, None, None]
    q = [vdp.jod(_shift(ref, a * sign), ref, 60)[0] for a in (1, 4, 16)]
    assert 10 > q[0] > q[1] > q[2]


def test_a_stronger_ghost_scores_lower(vdp):
    # a bright square moving over a grey field; the test leaves a trail of its last position
    f, h, w = 12, 36, 64
    ref = np.full((f, h, w, 3), 60, np.uint8)
    for t in range(f):
        ref[t, 12:24, 4 + 4 * t: 16 + 4 * t] = 220
    scores = []
    for alpha in (0.1, 0.3, 0.6):
        test = ref.copy()
        for t in range(1, f):
            trail = ref[t - 1].astype(np.float64)
            test[t] = np.round((1 - alpha) * ref[t] + alpha * np.maximum(trail, ref[t])).astype(np.uint8)
        scores.append(vdp.jod(test, ref, 60)[0])
    assert scores[0] > scores[1] > scores[2]


def test_bad_frames_are_refused(vdp):
    ref = _clip(frames=2)
    with pytest.raises(ValueError, match="8-bit"):
        vdp.jod(ref.astype(np.float32), ref, 60)
    with pytest.raises(ValueError, match="differ in shape"):
        vdp.jod(ref[:, :10], ref, 60)
    with pytest.raises(ValueError, match="frame rate"):
        vdp.jod(ref, ref, 0)


def test_our_call_gives_the_command_line_tools_jod(vdp, tmp_path):
    import imageio.v3 as iio
    ref = _clip(1, frames=8)
    test = _shift(ref, 6 * np.where(np.arange(8) % 2, 1, -1)[:, None, None, None])
    for i in range(8):           # BMP: the tool reads PNG through a FreeImage it would download
        iio.imwrite(tmp_path / f"r_{i:04d}.bmp", ref[i])
        iio.imwrite(tmp_path / f"t_{i:04d}.bmp", test[i])
    tool = shutil.which("cvvdp") or str(Path(__import__("sys").executable).parent / "cvvdp")
    out = subprocess.run([tool, "--test", "t_%04d.bmp", "--ref", "r_%04d.bmp", "--fps", "60", "--display",
                          "standard_fhd", "--device", "cpu", "-q"], cwd=tmp_path, capture_output=True, text=True,
                         env={**__import__("os").environ, "HF_HUB_OFFLINE": "1"}, timeout=300)
    assert out.returncode == 0, out.stderr
    assert float(out.stdout.split()[-1]) == pytest.approx(vdp.jod(test, ref, 60)[0], abs=1e-4)


STUDY = """
name = "video"
scenes = ["{moving}"]
resolution = [40, 24]
out = "out"
agreement = false
[[techniques]]
spec = "No AA=noaa"
[[techniques]]
spec = "Uncharted=taa_baseline"
[protocols.static]
history = 8
checkpoints = [1, 4, 8]
thesis_history = 4
[[protocols.ghosting]]
name = "ghosting"
frames = 4
[precision]
rule = "per_pixel"
[reference]
se_bound_lsb = 2.0
target_noise_db = 0.0
[video]
tests = ["ghosting", "static"]
fps = 30.0
"""


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    root = tmp_path_factory.mktemp("video_study")
    moving, _ = write_scenes(root)
    (root / "s.toml").write_text(STUDY.format(moving=moving))
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TAA_STUDY_CACHE", str(root / "cache"))
        mp.setenv("TAA_STUDY_WORKERS", "1")
        r = run_cli(["run", root / "s.toml"])
    return root, r.output


def test_the_ghosting_and_static_tables_carry_the_jod(study):
    root, output = study
    ghost = (root / "out" / "tables" / "ghosting_tiny_moving.md").read_text()
    row = next(line for line in ghost.splitlines() if line.startswith("| JOD (ColorVideoVDP)"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1] == "video, 30 fps" and all(0 < float(c) <= 10 for c in cells[2:4])
    assert "at 30 fps on its 'standard_fhd' display model" in ghost
    static = (root / "out" / "tables" / "static_tiny_moving.md").read_text()
    assert "| JOD (ColorVideoVDP) |" in static
    assert "video 3" in output or "video 4" in output     # No AA's static and ghosting, Uncharted's


def test_each_jod_is_the_jackknife_of_the_reference_and_its_halves_recomputed(study, vdp):
    """The record's figure judged against the full reference equals ColorVideoVDP of the run's
    frames against the reference's 8-bit frames, recomputed here; the filed JOD is the jackknife."""
    from display import DisplayTransform
    from references import ReferenceCache
    from study.engine.tasks import load_scene
    from study.engine.store import Store
    root, _ = study
    doc = json.loads((root / "out" / "tables" / "figures.json").read_text())
    ghost = next(t for t in doc["tests"] if t["protocol"] == "ghosting")
    store = Store(root / "cache")
    recs = [json.loads(p.read_text()) for p in sorted((root / "cache" / "video").rglob("done.json"))]
    rec = next(r for r in recs if "sequence" in r["data"]["jod"] and
               r["data"]["jod"]["sequence"] == ghost["techniques"]["Uncharted"]["jod"]["sequence"])
    q = rec["data"]["jod_judged"]["sequence"]
    assert rec["data"]["jod"]["sequence"] == pytest.approx(2 * q[""] - (q["a"] + q["b"]) / 2, abs=1e-9)
    assert ghost["techniques"]["Uncharted"]["jod_u"]["sequence"] == pytest.approx(abs(q["a"] - q["b"]), abs=1e-9)
    # recompute against the full reference from the cache
    scene = load_scene(str(root / "tiny_moving.toml"))
    cache = ReferenceCache(root / "cache")
    runs = [p.parent for p in (root / "cache" / "runs" / "ghosting").rglob("done.json")]
    frames = {}
    for folder in runs:
        run = json.loads((folder / "done.json").read_text())
        if run["technique"] == "taa_baseline":
            for f in range(4):
                ch = store.read_image(folder, f"frame_{f:04d}.exr", run)
                frames[f] = (np.stack([ch[c] for c in "RGB"], -1), run["output_space"])
    assert len(frames) == 4
    settings = {"se_bound_lsb": 2.0, "target_noise_db": 0.0}     # the per-pixel rule: all samples
    x8, r8 = [], []
    for f in range(4):
        ref = cache.get(scene, f, 40, 24, **settings)[0]
        probe = cache.get(scene, f, 40, 24, se_bound_lsb=8.0, target_noise_db=0.0, held_out=True)[0]   # the probe: held out
        disp = DisplayTransform.from_reference(probe.image)
        x8.append(disp.output(*frames[f])[2])
        r8.append(disp.to_8bit(ref.image))
    assert vdp.jod(np.stack(x8), np.stack(r8), 30)[0] == pytest.approx(q[""], abs=1e-3)


def test_the_heatmap_is_kept_like_the_flip_maps_and_shown(study):
    from references.exr import read_exr
    root, _ = study
    out = root / "out"
    assert (out / "plots" / "ghosting_cvvdp_tiny_moving.png").stat().st_size > 1000
    assert {p.name for p in (out / "maps").glob("*_cvvdp.png")} >= {"ghosting_tiny_moving_no_aa_cvvdp.png",
                                                                      "ghosting_tiny_moving_uncharted_cvvdp.png"}
    assert "plots/ghosting_cvvdp_tiny_moving.png" in (out / "report.html").read_text()
    maps = sorted((root / "cache" / "video").rglob("maps_*.exr"))
    assert maps
    _, ch = read_exr(maps[0])
    m = ch["cvvdp"]
    assert m.shape == (24, 40) and np.all(np.isfinite(m)) and m.min() >= 0


def test_ab_reports_the_jod_difference_with_its_interval(study):
    root, _ = study
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TAA_STUDY_CACHE", str(root / "cache"))
        mp.setenv("TAA_STUDY_WORKERS", "1")
        r = run_cli(["ab", "noaa", "taa_baseline", "--study", root / "s.toml", "--json"])
    doc = json.loads(r.output)
    jod = doc["per_scene"]["tiny_moving"]["jod"]
    assert jod["n"] == 2 and jod["mean"] is not None and math.isfinite(jod["mean"])
    assert doc["recomputed"]["video_computed"] == 0          # judged by the study already
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TAA_STUDY_CACHE", str(root / "cache"))
        mp.setenv("TAA_STUDY_WORKERS", "1")
        r = run_cli(["ab", "noaa", "taa_baseline", "--study", root / "s.toml", "--json", "--no-video"])
    assert json.loads(r.output)["per_scene"]["tiny_moving"]["jod"]["n"] == 0

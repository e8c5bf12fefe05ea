"""The study run is make-style: a second run recomputes nothing, a changed parameter recomputes
only that technique, and its tables are real files in the thesis's layout."""
import json

import pytest
from click.testing import CliRunner

from study.commands.cli import main
from study_fixtures import moving_scene

SCENE = moving_scene(frames=5, size=(48, 27), segments=16)
# The quick profile's protocols, short, for the make-style tests: what they prove (a second run
# recomputes nothing, a changed column recomputes its runs, an interrupted run is made again, the
# folder lists what belongs) holds for any length of run; its 256-frame static histories with 16
# checkpoints and 224-frame warm-ups were most of their runs' time; `run` (given --precision
# per_pixel) renders its references at 2 LSB, which none of them depends on. `ab` reads the file
# too, under the quick profile's figures' rule.
STUDY = """
name = "make_style"
resolution = "quick"
agreement = false
sweep = false
ghosting_skip = []
[[techniques]]
spec = "noaa"
[protocols.static]
history = 16
checkpoints = [1, 4, 16]
thesis_history = 16
[[protocols.ghosting]]
name = "ghosting"
frames = 24
warmup = 0
[[protocols.ghosting]]
name = "ghosting_warm"
frames = 24
warmup = 16
[video]
metric = "none"
[reference]
se_bound_lsb = 2.0
target_noise_db = 0.0
[precision]
rule = "figures"
psnr_db = 0.05
ssim = 5e-4
flip = 5e-4
relative = 0.0115
relmse = 0.05
"""
# no test here reads a plot: the studies draw none (conftest's no_plots; the report is still written)
pytestmark = pytest.mark.usefixtures("no_plots")


@pytest.fixture
def env(tmp_path, monkeypatch):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    (tmp_path / "tiny.toml").write_text(SCENE)
    (tmp_path / "study.toml").write_text(STUDY)
    return tmp_path


def _run(env, *techs, extra=()):
    args = ["run", str(env / "study.toml"), "--scenes", str(env / "tiny.toml"), "--out", str(env / "out"),
            "--no-agreement", "--precision", "per_pixel"]
    for t in techs:
        args += ["--techniques", t]
    r = CliRunner().invoke(main, args + list(extra), catch_exceptions=False)
    assert r.exit_code == 0, r.output
    return json.loads((env / "out" / "manifest.json").read_text())["summary"], r.output


@pytest.mark.long(seconds=22)
def test_second_run_recomputes_nothing_and_one_changed_parameter_recomputes_one_technique(env, reference_pool):
    a = "Uncharted=taa_baseline"
    b = "Improved=taa_improved"
    s1, out1 = _run(env, a, b)
    reference_pool.keep(env / "cache")          # for the tests below whose subject is not the references
    # static + cold and warm ghosting, two techniques
    assert s1["runs_computed"] == 6 and s1["runs_cached"] == 0
    assert s1["references_rendered"] == 2 * 5      # frame 0 shared by both tests; each with its probe (display_of)
    tables = env / "out" / "tables"
    static = (tables / "static_tiny_moving.md").read_text()
    assert "| PSNR (dB) |" in static and "| SSIM |" in static and "Improved vs best" in static
    assert (tables / "static_tiny_moving.tex").read_text().count("\\toprule") == 1
    assert "best (frame)" in (tables / "ghosting_tiny_moving.md").read_text()
    mtime = (tables / "static_tiny_moving.csv").stat().st_mtime_ns

    s2, _ = _run(env, a, b)
    assert s2["runs_computed"] == 0 and s2["metrics_computed"] == 0 and s2["references_rendered"] == 0
    assert (tables / "static_tiny_moving.csv").stat().st_mtime_ns == mtime   # unchanged, not rewritten

    s3, _ = _run(env, "Uncharted=taa_baseline:sharpen=normalised", b)
    assert s3["runs_computed"] == 3 and s3["runs_cached"] == 3 and s3["references_rendered"] == 0


def test_interrupted_run_folder_is_not_read_back(env, reference_pool):
    reference_pool.seed(env / "cache")
    _run(env, "Uncharted=taa_baseline")
    runs = list((env / "cache" / "runs" / "static" / "tiny_moving").iterdir())
    assert len(runs) == 1
    (runs[0] / "done.json").unlink()            # as if the run died before finishing
    s, _ = _run(env, "Uncharted=taa_baseline")
    assert s["runs_computed"] == 1


def test_bad_technique_is_refused(env):
    r = CliRunner().invoke(main, ["run", "--scenes", str(env / "tiny.toml"), "--techniques", "nope"])
    assert r.exit_code == 2 and "unknown technique" in r.output
    r = CliRunner().invoke(main, ["run", "--scenes", str(env / "tiny.toml"), "--techniques",
                                  "taa_baseline:k_min=2"])
    assert r.exit_code == 2 and "k_min" in r.output


@pytest.mark.long(seconds=20)
def test_ab_reports_paired_differences_and_gates(env):
    base = ["ab", "--scenes", str(env / "tiny.toml"), "--study", str(env / "study.toml"), "--json"]
    r = CliRunner().invoke(main, base + ["taa_baseline:sharpen=normalised", "taa_baseline:sharpen=xu",
                                         "--max-worse", "psnr=0.0"], catch_exceptions=False)
    out = json.loads(r.stdout)
    assert out["overall"]["psnr"]["n"] == 6                      # 1 static frame + 5 ghosting frames
    lo, hi = out["overall"]["psnr"]["ci"]
    assert lo <= out["overall"]["psnr"]["mean"] <= hi
    # Xu's unnormalised kernel over-sharpens: B is worse, and the gate says so with exit 1.
    assert out["overall"]["psnr"]["mean"] < 0 and "psnr" in out["failed"] and r.exit_code == 1
    # it says what it computed: both techniques' static and warm ghosting runs, and the references
    assert out["recomputed"]["runs_computed"] == 4 and out["recomputed"]["references_rendered"] > 0
    r = CliRunner().invoke(main, base + ["taa_baseline:sharpen=xu", "taa_baseline:sharpen=normalised",
                                         "--max-worse", "psnr=0.0"], catch_exceptions=False)
    assert r.exit_code == 0 and json.loads(r.stdout)["failed"] == {}
    assert json.loads(r.stdout)["recomputed"] == {"runs_computed": 0, "metrics_computed": 0, "references_rendered": 0,
                                                  "video_computed": 0, "runs_cached": 4}
    # one technique changed: only its runs (A's are cached); its figures may ask for finer
    # references (the figures' precision rule), and the line says how many were rendered
    r = CliRunner().invoke(main, ["ab", "--scenes", str(env / "tiny.toml"), "--study", str(env / "study.toml"),
                                  "taa_baseline:sharpen=xu",
                                  "taa_baseline:sharpen=none"], catch_exceptions=False)
    assert "recomputed: 2 runs (2 cached)" in r.output and " references rendered" in r.output, r.output
    r = CliRunner().invoke(main, base + ["taa_baseline", "taa_improved", "--max-worse", "psnr"])
    assert r.exit_code == 2 and "METRIC=THRESHOLD" in r.output


def test_out_folder_lists_the_report_keeps_the_user_s_files_and_refuses_a_foreign_folder(env, reference_pool):
    reference_pool.seed(env / "cache")
    mine = env / "mine"
    (mine / "tables").mkdir(parents=True)
    (mine / "tables" / "notes.md").write_text("my own notes")
    r = CliRunner().invoke(main, ["run", str(env / "study.toml"), "--scenes", str(env / "tiny.toml"), "--out", str(mine),
                                  "--no-agreement",
                                  "--precision", "per_pixel",
                                  "--techniques", "No AA=noaa"])
    assert r.exit_code == 2 and "no manifest.json" in r.output and str(mine) in r.output, r.output
    assert sorted(p.name for p in mine.rglob("*")) == ["notes.md", "tables"]       # nothing written

    _run(env, "No AA=noaa", "FXAA=fxaa")
    out = env / "out"
    man = json.loads((out / "manifest.json").read_text())["artefacts"]
    assert "report.html" in man                                   # the manifest lists everything that belongs
    assert not any(rel.startswith("plots/") for rel in man) and not (out / "plots").exists()   # no_plots
    import hashlib
    assert man["report.html"]["sha256"] == hashlib.sha256((out / "report.html").read_bytes()).hexdigest()
    fxaa = [rel for rel in man if "fxaa" in rel]
    assert fxaa and all((out / rel).exists() for rel in fxaa)
    (out / "tables" / "notes.md").write_text("my own notes")        # not the study's: no manifest lists it
    s, _ = _run(env, "No AA=noaa")
    assert not any((out / rel).exists() for rel in fxaa)         # the previous manifest's, not written again
    assert (out / "tables" / "notes.md").read_text() == "my own notes"
    assert s["stale_files_removed"] == len(fxaa)


def test_a_truncated_reference_is_remade_counted_and_reported_once(env, capfd):
    from references.exr import read_exr
    _run(env, "No AA=noaa")
    frame0 = [p for p in (env / "cache" / "references").rglob("*.exr")
              if read_exr(p)[0]["taa_frame"] == 0 and read_exr(p)[0]["taa_bound_lsb"] == 2.0]   # not its probe
    assert len(frame0) == 1
    frame0[0].write_bytes(frame0[0].read_bytes()[:3000])
    capfd.readouterr()
    s, out = _run(env, "No AA=noaa")
    assert s["references_rendered"] == 1, s
    assert out.count("is corrupt") == 1 and "removing it and rendering again" in out, out
    assert "EXR_ERR" not in capfd.readouterr().err      # the library's own lines are in the message, once
    assert read_exr(frame0[0])[0]["taa_frame"] == 0      # re-made in place

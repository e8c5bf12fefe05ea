"""A study without the video metric ([video] metric = "none", as the thesis profile at 1600x900)
says in its ghosting tables why it has no JOD and where one is; [video] device picks torch's device
for the metric (study.metrics.video.torch_device), and a bad one is refused naming the field."""
import pytest

from study_fixtures import run_cli, write_scenes

STUDY = """
name = "no_video"
scenes = ["{moving}"]
resolution = [40, 24]
out = "out"
agreement = false
[[techniques]]
spec = "No AA=noaa"
[protocols.static]
history = 2
checkpoints = [1, 2]
thesis_history = 2
[[protocols.ghosting]]
name = "ghosting"
frames = 3
[precision]
rule = "per_pixel"
[reference]
se_bound_lsb = 4.0
target_noise_db = 0.0
[video]
metric = "none"
"""


@pytest.mark.long(seconds=15)
def test_a_study_without_the_video_metric_says_so_in_its_ghosting_table(tmp_path, monkeypatch, no_plots):
    moving, _ = write_scenes(tmp_path)
    (tmp_path / "s.toml").write_text(STUDY.format(moving=moving))
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("TAA_STUDY_WORKERS", "1")
    run_cli(["run", tmp_path / "s.toml"])
    out = tmp_path / "out"
    ghost = (out / "tables" / "ghosting_tiny_moving.md").read_text()
    assert "| JOD (ColorVideoVDP)" not in ghost
    assert ('JOD not computed at 40x24: this study\'s [video] metric is "none" (ColorVideoVDP costs about 6 s '
            "per technique-frame at 1600x900 on one CPU core") in ghost
    assert "out/quick/tables/ghosting_*" in ghost and '[video] metric = "cvvdp" on a CUDA device' in ghost
    assert "JOD not computed at 40x24" in (out / "tables" / "ghosting_tiny_moving.tex").read_text()
    assert "JOD not computed at 40x24" in (out / "report.html").read_text()      # the table's note there too


@pytest.mark.parametrize("device, cuda, want", [
    ("auto", True, "cuda"), ("auto", False, "cpu"), ("cpu", True, "cpu"), ("cuda", True, "cuda")])
def test_the_device_setting_picks_cuda_where_torch_sees_one(device, cuda, want):
    from study.metrics.video import torch_device
    assert torch_device(device, cuda) == want


def test_cuda_without_a_device_and_an_unknown_device_are_refused():
    from study.metrics.video import torch_device
    with pytest.raises(ValueError, match=r"\[video\] device = 'cuda': torch sees no CUDA device"):
        torch_device("cuda", False)
    with pytest.raises(ValueError, match=r"\[video\] device = 'gpu': expected 'auto', 'cpu' or 'cuda'"):
        torch_device("gpu", True)


def test_the_device_field_is_checked_with_the_study_file(tmp_path):
    from study.config.studyfile import load_study
    f = tmp_path / "bad.toml"
    f.write_text('name = "x"\n[video]\ndevice = "gpu"\n')
    r = run_cli(["run", f], code=2)
    assert "field video.device" in r.output and "'gpu'" in r.output and str(f) in r.output
    assert "Traceback" not in r.output
    f.write_text('name = "x"\n[video]\ndevice = "cuda"\n')
    assert load_study(f).video.task_data()["device"] == "cuda"
    assert "device" not in load_study(f).video.key_data()        # the same JOD on either: keyed alike


def test_the_video_metric_judges_only_the_protocols_named_and_a_bad_name_is_refused(tmp_path):
    from types import SimpleNamespace
    from study.config.profile import get_profile
    from study.config.studyfile import load_study
    from study.config.video import Video
    col = SimpleNamespace(label="Improved", name="taa_improved")
    v = Video(tests=("ghosting",), protocols=("ghosting",))
    assert v.judges("ghosting", "s", col, "ghosting") and not v.judges("ghosting", "s", col, "ghosting_warm")
    assert Video(tests=("ghosting",)).judges("ghosting", "s", col, "ghosting_warm")     # none named: every one
    q = get_profile("quick").video          # the thesis's protocol (cold) alone
    assert q.protocols == ("ghosting",) and not q.judges("ghosting", "sphere_ghosting", col, "ghosting_warm")
    f = tmp_path / "bad.toml"
    f.write_text('name = "x"\n[[protocols.ghosting]]\nname = "cold"\n[video]\nprotocols = ["cold", "warm"]\n')
    r = run_cli(["run", f], code=2)
    assert "video.protocols[1]" in r.output and "'warm'" in r.output and "static, cold" in r.output, r.output
    assert "Traceback" not in r.output
    f.write_text('name = "x"\n[[protocols.ghosting]]\nname = "cold"\n[video]\nprotocols = ["cold"]\n')
    assert load_study(f).video.protocols == ("cold",)

"""CLI values are validated by click: exit 2 with a message, no traceback."""
import json

import pytest
from click.testing import CliRunner

from study.commands.cli import main
from study_fixtures import write_scenes


def _invoke(args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.mark.parametrize("args, message", [
    (["render", "--scene", "pipe", "--width", "-5", "--out", "x"], "--width"),
    (["render", "--scene", "pipe", "--width", "0", "--out", "x"], "--width"),
    (["agree", "--scene", "pipe", "--height", "-1"], "--height"),
    (["bench", "--repeats", "0"], "--repeats"),
    (["bench", "--technique", "nosuch"], "unknown technique(s) nosuch"),
    (["run", "--scenes", ","], "empty scene"),
    (["run", "--scenes", "pipe,,atrium"], "empty scene"),
    (["run", "--workers", "0"], "--workers"),
    (["run", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "not both"),
    (["ab", "taa_baseline", "taa_improved", "--scenes", ""], "empty scene"),
])
def test_bad_values_exit_2_with_a_message(args, message):
    r = _invoke(args)
    assert r.exit_code == 2, r.output
    assert message in r.output and "Traceback" not in r.output


def test_duplicate_scenes_are_taken_once_with_a_note(tmp_path, monkeypatch, no_plots):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    _, still = write_scenes(tmp_path)
    r = _invoke(["run", "--scenes", f"{still},{still}", "--no-agreement", "--techniques", "noaa",
                 "--out", tmp_path / "out"])
    assert r.exit_code == 0, r.output
    assert "duplicate scene(s)" in r.stderr
    rows = (tmp_path / "out" / "tables" / "headline.csv").read_text().splitlines()[1:]
    assert len(rows) == 2                           # one scene, two labelled protocols


def test_ab_with_one_pair_says_n_1_and_json_is_strict(tmp_path, monkeypatch):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    _, still = write_scenes(tmp_path)
    r = _invoke(["ab", "noaa", "fxaa", "--scenes", still, "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout, parse_constant=lambda c: pytest.fail(f"non-strict JSON constant {c}"))
    assert out["overall"]["psnr"]["n"] == 1 and out["overall"]["psnr"]["ci"] is None
    assert isinstance(out["overall"]["psnr"]["mean"], float)
    r = _invoke(["ab", "noaa", "fxaa", "--scenes", still])
    assert "no interval: one pair" in r.stdout


def test_run_with_a_nan_camera_exits_2_before_anything_renders(tmp_path, monkeypatch):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    _, still = write_scenes(tmp_path)
    bad = tmp_path / "bad.toml"
    bad.write_text(open(still).read().replace("position = [0.0, 0.0, 4.0]", "position = [0.0, nan, 4.0]"))
    r = _invoke(["run", "--scenes", bad, "--techniques", "noaa", "--out", tmp_path / "out"])
    assert r.exit_code == 2 and "camera.position" in r.output and "nan" in r.output.lower()
    assert "Traceback" not in r.output
    assert not (tmp_path / "cache").exists() and not (tmp_path / "out").exists()

"""`run --stop-after`: a study stops taking tasks at its deadline, exits 3 writing nothing, and the
same command again finishes it, recomputing nothing that finished, to the same figures."""
import json
import re
from itertools import count

import pytest
from click.testing import CliRunner

from study.commands.cli import main
from study.commands.study_commands import parse_duration
from study.engine import execute
from study_fixtures import STILL, moving_scene

MOVING = moving_scene(frames=2, size=(32, 18), segments=8)
# short protocols, two columns, no video metric: the whole study in seconds
STUDY = """
name = "stop"
scenes = ["moving.toml", "still.toml"]
agreement = false
[[techniques]]
spec = "Uncharted=taa_baseline"
[[techniques]]
spec = "FXAA=fxaa"
[protocols.static]
history = 16
checkpoints = [4, 16]
[[protocols.ghosting]]
name = "ghosting"
frames = 2
[precision]
rule = "per_pixel"
[video]
metric = "none"
"""
COMPUTED = re.compile(r"computed before it: runs (\d+), metrics (\d+), references (\d+)")


def test_durations_parse_to_seconds():
    assert parse_duration("90m") == 5400 and parse_duration("2h") == 7200 and parse_duration("3600s") == 3600
    assert parse_duration("1h30m") == 5400 and parse_duration("1.5h") == 5400 and parse_duration("0s") == 0
    for bad in ("", "90", "5x", "-1h", "h", "1h 30m", "m90"):
        with pytest.raises(ValueError):
            parse_duration(bad)


@pytest.mark.parametrize("value", ["5x", "90", "-2h", "soon"])
def test_a_bad_duration_exits_2_naming_the_option_and_the_value(value):
    r = CliRunner().invoke(main, ["run", "--scenes", "pipe", "--stop-after", value])
    assert r.exit_code == 2 and "--stop-after" in r.output and repr(value) in r.output, r.output
    r = CliRunner().invoke(main, ["ab", "taa_baseline", "taa_improved", "--stop-after", value])
    assert r.exit_code == 2 and "--stop-after" in r.output, r.output


def _invoke(args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def _computed(output) -> dict:
    m = COMPUTED.search(output)
    assert m, output
    return dict(zip(("runs_computed", "metrics_computed", "references_rendered"), map(int, m.groups())))


@pytest.mark.long(seconds=30)
def test_a_stopped_study_resumes_to_an_uninterrupted_one_s_figures_recomputing_nothing(tmp_path, monkeypatch, no_plots):
    (tmp_path / "moving.toml").write_text(MOVING)
    (tmp_path / "still.toml").write_text(STILL)
    (tmp_path / "study.toml").write_text(STUDY)
    base = ["run", tmp_path / "study.toml", "--workers", "1"]

    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache_a"))
    whole = _invoke(base + ["--out", tmp_path / "a"])
    assert whole.exit_code == 0, whole.output
    sa = json.loads((tmp_path / "a" / "manifest.json").read_text())["summary"]

    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache_b"))
    out = tmp_path / "b"
    # at once: nothing starts, nothing is written
    r = _invoke(base + ["--out", out, "--stop-after", "0s"])
    assert r.exit_code == 3, r.output
    assert "run the same command again" in r.output and "--stop-after" in r.output
    assert _computed(r.output) == dict.fromkeys(("runs_computed", "metrics_computed", "references_rendered"), 0)
    assert not out.exists() or not any(out.iterdir())

    # a clock that passes the hour's deadline after its 6th reading (the deadline itself, the round's
    # check, then four tasks start): the study stops with those four done and the rest not started
    ticks = count()
    monkeypatch.setattr(execute, "now", lambda: 0.0 if next(ticks) < 6 else 1e9)
    r = _invoke(base + ["--out", out, "--stop-after", "1h"])
    assert r.exit_code == 3, r.output
    assert "tasks not started" in r.output and not (out / "manifest.json").exists()
    first = _computed(r.output)
    assert sum(first.values()) >= 1, r.output
    monkeypatch.undo()
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache_b"))
    monkeypatch.setenv("TAA_STUDY_PLOTS", "0")       # undone with the clock (no_plots)

    r = _invoke(base + ["--out", out])
    assert r.exit_code == 0, r.output
    sb = json.loads((out / "manifest.json").read_text())["summary"]
    for k, n in first.items():      # what the stopped run finished is not made again
        assert sb[k] + n == sa[k], (k, sa, sb, first)
    assert sb["runs_cached"] == first["runs_computed"] and sb["runs_computed"] > 0
    assert (out / "tables" / "figures.json").read_bytes() == (tmp_path / "a" / "tables" / "figures.json").read_bytes()


def test_ab_stops_at_its_deadline_too(tmp_path, monkeypatch):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    (tmp_path / "still.toml").write_text(STILL)
    r = _invoke(["ab", "taa_baseline", "taa_improved", "--scenes", tmp_path / "still.toml", "--workers", "1",
                 "--no-video", "--stop-after", "0s"])
    assert r.exit_code == 3, r.output
    assert "run the same command again" in r.output

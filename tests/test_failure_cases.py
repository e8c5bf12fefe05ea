"""Inputs and environments that used to give a traceback, lose files or pass a gate silently:
each exits 2 naming the problem (file, field, value, folder) and leaves nothing half-written."""
import os
import socket
import subprocess
import threading
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from study.commands.cli import main
from study.config.profile import get_profile
from study.config.studyfile import load_study
from study.engine.store import Store


def test_a_study_file_without_techniques_compares_the_default_set(tmp_path):
    for text in ('name = "a"\n', 'name = "b"\ntechniques = []\n'):
        f = tmp_path / "s.toml"
        f.write_text(text)
        labels = [c.label for c in load_study(f).techniques]
        assert labels == [c.label for c in get_profile("quick").techniques], labels
        assert labels[:5] == ["No AA", "FXAA", "SMAA", "Uncharted", "Improved"] and len(labels) == 13, labels
        assert labels[-1] == "Accumulation 128" and not any("×" in l for l in labels), labels
    # the upscalers, one column per render scale, are the full profile's (13 output-size columns before them)
    full = [c.label for c in get_profile("full").techniques]
    assert full[13:24] == [f"{u} ×{s}" for u in ("FSR 2", "TAAU") for s in ("0.5", "0.67", "0.77", "1")] + \
        [f"Lanczos ×{s}" for s in ("0.5", "0.67", "0.77")], full


@pytest.mark.parametrize("args, words", [
    (["ab", "noaa", "fxaa", "--scenes", "pipe", "--max-worse", "psnr=nan"], ["psnr=nan", "finite number >= 0"]),
    (["ab", "noaa", "fxaa", "--scenes", "pipe", "--max-worse", "ssim=-0.1"], ["ssim=-0.1", "finite number >= 0"]),
    (["ab", "noaa", "fxaa", "--scenes", "pipe", "--max-worse", "mse=inf"], ["mse=inf", "finite number >= 0"]),
    (["run", "--scenes", "pipe", "--techniques", "taa_baseline:nosuch=1"],
     ["taa_baseline:nosuch=1", "unknown parameter 'nosuch'", "its parameters: k_min, k_max"]),
])
def test_bad_options_exit_2_naming_the_value(args, words, tmp_path, monkeypatch):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2, r.output
    for w in words:
        assert w in r.output, (w, r.output)
    assert not (tmp_path / "cache").exists() or not any((tmp_path / "cache").rglob("*.exr"))


def test_a_folder_given_as_a_scene_file(tmp_path):
    for d in (tmp_path / "scene.toml", tmp_path / "scenes"):
        d.mkdir()
        r = CliRunner().invoke(main, ["agree", "--scene", str(d)])
        assert r.exit_code == 2 and f"{d}: is a folder, not a scene file" in r.output, r.output


@pytest.mark.parametrize("command", [
    ["run", "--scenes", "pipe", "--techniques", "noaa"],
    ["render", "--scene", "pipe", "--width", "16", "--height", "9"],
    ["agree", "--scene", "pipe", "--width", "16", "--height", "9"],
    ["estimate", "--scenes", "pipe"],
])
def test_a_cache_that_is_a_file(command, tmp_path, monkeypatch):
    bad = tmp_path / "cache"
    bad.write_text("not a folder")
    monkeypatch.setenv("TAA_STUDY_CACHE", str(bad))
    out = tmp_path / "out"
    extra = ["--out", str(out)] if command[0] in ("run", "render") else []
    r = CliRunner().invoke(main, command + extra)
    assert r.exit_code == 2, r.output
    assert f"the cache folder (TAA_STUDY_CACHE) {bad}: exists and is not a folder" in r.output, r.output
    assert not out.exists() or not any(out.rglob("*.exr")), sorted(out.rglob("*"))   # render wrote nothing


def test_an_output_folder_that_is_a_file(tmp_path, monkeypatch):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    (tmp_path / "out").write_text("x")
    for cmd in (["run", "--scenes", "pipe", "--techniques", "noaa"], ["render", "--scene", "pipe"]):
        r = CliRunner().invoke(main, cmd + ["--out", str(tmp_path / "out")])        # click's own check
        assert r.exit_code == 2 and str(tmp_path / "out") in r.output and "is a file" in r.output, r.output
    study = tmp_path / "s.toml"                                                     # the study file's out
    study.write_text('name = "s"\nscenes = ["pipe"]\nout = "out"\n[[techniques]]\nspec = "noaa"\n')
    r = CliRunner().invoke(main, ["run", str(study)])
    assert r.exit_code == 2 and f"--out {tmp_path / 'out'}: exists and is not a folder" in r.output, r.output


def test_a_cache_under_a_file_cannot_be_made(tmp_path, monkeypatch):
    # (as root every existing folder is writable; a path through a file fails as a read-only or
    # foreign folder does: the folder cannot be made or written)
    (tmp_path / "f").write_text("x")
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "f" / "cache"))
    r = CliRunner().invoke(main, ["estimate", "--scenes", "pipe"])
    assert r.exit_code == 2, r.output
    assert f"the cache folder (TAA_STUDY_CACHE) {tmp_path / 'f' / 'cache'}: cannot write there (Not a directory)" \
        in r.output, r.output


def test_a_lock_of_a_dead_process_is_broken_at_once(tmp_path):
    logs = []
    store = Store(tmp_path, log=logs.append)
    dead = subprocess.Popen(["true"])
    dead.wait()                                          # a pid of this host that no longer exists
    lock = tmp_path / "locks" / "k.lock"
    lock.parent.mkdir(parents=True)
    lock.write_text(f"{socket.gethostname()} {dead.pid} 1")
    t0 = time.perf_counter()
    with store.lock("k", stale_s=60):
        assert lock.read_text().split()[1] == str(os.getpid())
    assert time.perf_counter() - t0 < 5
    assert any("its process is gone" in m and str(dead.pid) in m for m in logs), logs


def test_a_lock_of_a_killed_process_not_yet_reaped_is_broken_at_once(tmp_path):
    """A worker killed by its user stays a zombie until its parent reaps it, and a zombie still
    answers signal 0: the lock waited its 60-s heartbeat out (the killed-worker test's 50 s)."""
    logs = []
    store = Store(tmp_path, log=logs.append)
    zombie = subprocess.Popen(["sleep", "30"])
    try:
        zombie.kill()
        deadline = time.time() + 5
        while time.time() < deadline and Path(f"/proc/{zombie.pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z":
            time.sleep(0.01)
        os.kill(zombie.pid, 0)                           # not reaped: the pid still exists
        lock = tmp_path / "locks" / "k.lock"
        lock.parent.mkdir(parents=True)
        lock.write_text(f"{socket.gethostname()} {zombie.pid} 1")
        t0 = time.perf_counter()
        with store.lock("k", stale_s=60):
            pass
        assert time.perf_counter() - t0 < 5
        assert any("its process is gone" in m and str(zombie.pid) in m for m in logs), logs
    finally:
        zombie.wait()


def test_a_lock_of_a_live_process_or_another_host_is_waited_for(tmp_path):
    store = Store(tmp_path, log=lambda m: None)
    lock = tmp_path / "locks" / "k.lock"
    lock.parent.mkdir(parents=True)
    for owner in (f"{socket.gethostname()} {os.getppid()} 1", f"elsewhere-{socket.gethostname()} 1 1"):
        lock.write_text(owner)
        got = threading.Event()

        def take():
            with store.lock("k", stale_s=60, poll_s=0.05):
                got.set()
        th = threading.Thread(target=take, daemon=True)
        th.start()
        assert not got.wait(1.0), owner                  # still held: not broken
        lock.unlink()                                    # the owner finishes
        assert got.wait(5.0), owner
        th.join(5)

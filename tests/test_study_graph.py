"""The study as a task graph: the same numbers in-process and on a Dask LocalCluster, a killed
worker's task run again, and two studies on one cache computing each key once."""
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from study_fixtures import numbers, run_cli, summary, write_scenes

TECHS = ["--techniques", "taa_baseline", "--techniques", "fxaa", "--techniques", "noaa"]


@pytest.fixture
def scenes(tmp_path):
    return write_scenes(tmp_path)


def _study(tmp_path, scenes, name, cache, *extra):
    out = tmp_path / name
    run_cli(["run", "--scenes", ",".join(scenes), "--out", out, "--no-agreement", *TECHS, *extra], code=0) \
        if cache is None else None
    return out


def test_local_cluster_gives_the_in_process_numbers_and_survives_a_killed_worker(tmp_path, scenes, monkeypatch):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache_a"))
    base = ["run", "--scenes", ",".join(scenes), "--no-agreement", *TECHS]
    run_cli(base + ["--out", tmp_path / "a"])
    s_a = summary(tmp_path / "a")
    assert s_a["runs_computed"] == 3 * 3 + 3 and s_a["executor"] == "in-process"  # 2 statics + 2 ghosting x 3

    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache_b"))
    run_cli(base + ["--out", tmp_path / "b", "--workers", "2"])
    s_b = summary(tmp_path / "b")
    assert s_b["executor"].startswith("LocalCluster, 2 worker") and s_b["runs_computed"] == s_a["runs_computed"]
    assert numbers(tmp_path / "b") == numbers(tmp_path / "a")

    # A worker killed while the study runs on a cluster: its task runs again elsewhere.
    from distributed import Client, LocalCluster
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache_c"))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, \
            Client(cluster) as client:
        pids = list(client.run(os.getpid).values())
        killed = []

        def killer():
            runs = tmp_path / "cache_c" / "runs"
            deadline = time.time() + 120
            while time.time() < deadline and not list(runs.glob("*/*/*/done.json")):
                time.sleep(0.05)
            os.kill(pids[0], signal.SIGKILL)      # mid-study: some tasks done, others running
            killed.append(pids[0])
        th = threading.Thread(target=killer)
        th.start()
        run_cli(base + ["--out", tmp_path / "c", "--scheduler", cluster.scheduler_address])
        th.join()
    assert killed
    assert numbers(tmp_path / "c") == numbers(tmp_path / "a")


def test_two_concurrent_studies_on_one_cache_compute_each_key_once(tmp_path, scenes):
    env = {**os.environ, "TAA_STUDY_CACHE": str(tmp_path / "cache")}
    cmd = [sys.executable, "-m", "study", "run", "--scenes", ",".join(scenes), "--no-agreement", *TECHS]
    procs = [subprocess.Popen(cmd + ["--out", str(tmp_path / f"s{i}")], env=env, cwd=Path(__file__).parent.parent,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT) for i in range(2)]
    outs = [p.communicate(timeout=600)[0].decode() for p in procs]
    assert all(p.returncode == 0 for p in procs), outs
    s = [summary(tmp_path / f"s{i}") for i in range(2)]
    assert s[0]["runs_computed"] + s[1]["runs_computed"] == 12           # each run key once
    assert s[0]["metrics_computed"] + s[1]["metrics_computed"] == 12
    assert s[0]["references_rendered"] + s[1]["references_rendered"] == 5  # 4 moving frames + 1 still
    assert numbers(tmp_path / "s0") == numbers(tmp_path / "s1")

"""The study as a task graph: the same numbers in-process and on a Dask LocalCluster, a killed
worker's task run again, and two studies on one cache computing each key once. Clusters run in
their own processes (as a user would start them), so no event loop outlives a test."""
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from study_fixtures import numbers, run_cli, summary, write_scenes

ROOT = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).parent
TECHS = ["--techniques", "taa_baseline", "--techniques", "fxaa", "--techniques", "noaa"]
# Their studies draw no plot (conftest's no_plots): none is read here, and drawing them was a third
# of each study process's CPU time. The first study below draws them, the check that they change
# no table.
pytestmark = pytest.mark.usefixtures("no_plots")


# The quick profile's protocols, short, and references at 2 LSB: what these tests prove (the
# executors agree, a killed worker's task runs again, each key computed once) holds for any length
# of run and any reference precision, and the quick profile's 256-frame static runs and 224-frame
# warm-ups were most of their time.
STUDY = """
name = "graph"
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
frames = 4
warmup = 0
[[protocols.ghosting]]
name = "ghosting_warm"
frames = 4
warmup = 16
[video]
metric = "none"
[reference]
se_bound_lsb = 2.0
target_noise_db = 0.0
[precision]
rule = "per_pixel"
psnr_db = 0.05
ssim = 5e-4
flip = 5e-4
relative = 0.0115
relmse = 0.05
"""


@pytest.fixture
def scenes(tmp_path):
    (tmp_path / "graph.toml").write_text(STUDY)
    return write_scenes(tmp_path)


def _study_file(scenes) -> str:
    return str(Path(scenes[0]).parent / "graph.toml")


def _study_cmd(scenes, out, *extra):
    return [sys.executable, "-m", "study", "run", _study_file(scenes), "--scenes", ",".join(scenes), "--no-agreement",
            "--precision", "per_pixel", *TECHS,
            "--out", str(out), *extra]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.long(seconds=30)
def test_local_cluster_gives_the_in_process_numbers_and_survives_a_killed_worker(tmp_path, scenes, monkeypatch):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache_a"))
    monkeypatch.delenv("TAA_STUDY_PLOTS")          # this study draws its plots, the others none
    run_cli(["run", _study_file(scenes), "--scenes", ",".join(scenes), "--no-agreement", "--precision", "per_pixel",
             *TECHS, "--out", tmp_path / "a"])
    monkeypatch.setenv("TAA_STUDY_PLOTS", "0")
    s_a = summary(tmp_path / "a")
    # 2 statics x 3, cold ghosting x 3, warm ghosting only the TAA: No AA and FXAA have no history,
    # so their warm runs are their cold ones (study.engine.plan.run_steps)
    assert s_a["runs_computed"] == 2 * 3 + 3 + 1 and s_a["executor"] == "in-process"
    figures = json.loads((tmp_path / "a" / "tables" / "figures.json").read_text())["tests"]
    cold, warm = (next(t["techniques"] for t in figures if (t["scene"], t["protocol"]) == ("tiny_moving", p))
                  for p in ("ghosting", "ghosting_warm"))
    assert cold["fxaa"] == warm["fxaa"] and cold["noaa"] == warm["noaa"]
    assert all(cold["taa_baseline"]["frames"][f]["figures"] != warm["taa_baseline"]["frames"][f]["figures"]
               for f in cold["taa_baseline"]["frames"])                      # the TAA's warm history

    env = {**os.environ, "TAA_STUDY_CACHE": str(tmp_path / "cache_b")}
    r = subprocess.run(_study_cmd(scenes, tmp_path / "b", "--workers", "2"), env=env, cwd=ROOT,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "Dask dashboard:" in r.stderr
    s_b = summary(tmp_path / "b")
    assert s_b["executor"].startswith("LocalCluster, 2 worker") and s_b["runs_computed"] == s_a["runs_computed"]
    assert numbers(tmp_path / "b") == numbers(tmp_path / "a")
    # with TAA_STUDY_PLOTS=0 the same tables and report, and no plot made or listed
    listed = {d: set(json.loads((tmp_path / d / "manifest.json").read_text())["artefacts"]) for d in "ab"}
    assert {r for r in listed["a"] if r.startswith("plots/")} >= {"plots/overview.png", "plots/speed_error.png"}
    assert listed["b"] == {r for r in listed["a"] if not r.startswith("plots/")}
    assert not (tmp_path / "b" / "plots").exists() or not any((tmp_path / "b" / "plots").iterdir())

    # A scheduler and two workers; one worker is killed (SIGKILL) once the first run is filed.
    # Its cache starts with the references the in-process study made (content-keyed files): the
    # cluster has just rendered its own in cache_b, and what this part proves is the recovery.
    env = {**os.environ, "TAA_STUDY_CACHE": str(tmp_path / "cache_c")}
    shutil.copytree(tmp_path / "cache_a" / "references", tmp_path / "cache_c" / "references")
    port = _free_port()
    addr = f"tcp://127.0.0.1:{port}"
    procs = [subprocess.Popen([str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--dashboard-address", ":0"], env=env, cwd=ROOT,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        _wait_listening(port, procs[0])     # a study refuses a scheduler that is not up yet
        workers = [subprocess.Popen([str(BIN / "dask"), "worker", addr, "--nthreads", "1", "--no-nanny",
                                     "--no-dashboard"], env=env, cwd=ROOT,
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(2)]
        procs += workers
        study = subprocess.Popen(_study_cmd(scenes, tmp_path / "c", "--scheduler", addr), env=env, cwd=ROOT,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        runs = tmp_path / "cache_c" / "runs"
        deadline = time.time() + 300
        while time.time() < deadline and not list(runs.glob("*/*/*/done.json")) and study.poll() is None:
            time.sleep(0.05)
        assert study.poll() is None, "the study ended before a worker could be killed"
        os.kill(workers[0].pid, signal.SIGKILL)     # mid-study: some tasks done, others running
        out, err = study.communicate(timeout=600)
        assert study.returncode == 0, err[-3000:]
    finally:
        for p in procs:
            p.kill()
            p.wait()
    assert numbers(tmp_path / "c") == numbers(tmp_path / "a")


def _wait_listening(port: int, proc, seconds: float = 120.0) -> None:
    """Until something accepts connections on the port (a loaded machine takes seconds to start Dask)."""
    deadline = time.time() + seconds
    while time.time() < deadline:
        assert proc.poll() is None, "the Dask scheduler ended before it listened"
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return
        except OSError:
            time.sleep(0.1)
    raise AssertionError(f"no Dask scheduler listening on port {port} after {seconds:.0f} s")


def test_two_concurrent_studies_on_one_cache_compute_each_key_once(tmp_path, scenes):
    env = {**os.environ, "TAA_STUDY_CACHE": str(tmp_path / "cache")}
    procs = [subprocess.Popen(_study_cmd(scenes, tmp_path / f"s{i}"), env=env, cwd=ROOT,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT) for i in range(2)]
    outs = [p.communicate(timeout=600)[0].decode() for p in procs]
    assert all(p.returncode == 0 for p in procs), outs
    s = [summary(tmp_path / f"s{i}") for i in range(2)]
    assert s[0]["runs_computed"] + s[1]["runs_computed"] == 10           # each run key once
    assert s[0]["metrics_computed"] + s[1]["metrics_computed"] == 10
    assert s[0]["references_rendered"] + s[1]["references_rendered"] == 2 * 5  # 4 moving frames + 1 still, and their probes
    assert numbers(tmp_path / "s0") == numbers(tmp_path / "s1")


def test_a_deterministic_failure_stops_every_executor_with_the_same_message(tmp_path, scenes):
    """A technique that outputs NaN: exit 2 and one clear message, in-process and on a cluster."""
    (tmp_path / "nan_taa.py").write_text(
        "import numpy as np\nfrom taa_impl.simple import NoAA\n"
        "class NaNAA(NoAA):\n    name = 'nan_aa'\n"
        "    def process(self, frame, **kw):\n        return np.full(frame['color'].shape, np.nan, np.float32)\n")
    cmd = [sys.executable, "-m", "study", "run", _study_file(scenes), "--scenes", scenes[1], "--no-agreement", "--techniques",
           f"Bad={tmp_path / 'nan_taa.py'}:NaNAA"]
    msgs = []
    for i, extra in enumerate(([], ["--workers", "2"])):
        env = {**os.environ, "TAA_STUDY_CACHE": str(tmp_path / f"cache{i}")}
        r = subprocess.run(cmd + ["--out", str(tmp_path / f"o{i}")] + extra, env=env, cwd=ROOT,
                           capture_output=True, text=True, timeout=600)
        assert r.returncode == 2, r.stderr[-3000:]
        assert "Traceback" not in r.stderr
        msgs.append([line for line in r.stderr.splitlines() if line.startswith("error:")])
        assert not (tmp_path / f"o{i}" / "manifest.json").exists()     # no half-written output
    assert msgs[0] == msgs[1] and len(msgs[0]) == 1
    assert "technique 'Bad' produced NaN/Inf" in msgs[0][0]


def test_a_task_that_ends_its_worker_process_is_named_with_its_likely_cause(tmp_path, scenes):
    """A worker process that dies under a task (here the technique's own exit; at scale, memory past
    the worker's limit) until Dask gives up (its KilledWorker; no retry here): exit 2, one message
    naming the task and the likely cause, no traceback, no output."""
    (tmp_path / "dies.py").write_text(
        "import os\nfrom taa_impl.simple import NoAA\n"
        "class Dies(NoAA):\n    name = 'dies'\n"
        "    def process(self, frame, **kw):\n        os._exit(1)\n")
    env = {**os.environ, "TAA_STUDY_CACHE": str(tmp_path / "cache"),
           "DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "0"}
    r = subprocess.run([sys.executable, "-m", "study", "run", _study_file(scenes), "--scenes", scenes[1],
                        "--no-agreement", "--techniques", f"Bad={tmp_path / 'dies.py'}:Dies", "--workers", "2",
                        "--out", str(tmp_path / "o")], env=env, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 2, r.stderr[-3000:]
    assert "Traceback" not in r.stderr
    (msg,) = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    assert f"a run task of scene {scenes[1]}" in msg and "ended its worker process each time it ran" in msg, msg
    assert "shared by 2 workers" in msg and "Fewer --workers" in msg, msg
    assert not (tmp_path / "o" / "manifest.json").exists()


def test_the_default_executor_shares_the_cores_and_runs_a_small_plan_in_process(monkeypatch):
    from study.commands.common import _executor
    from study.engine import execute as E
    monkeypatch.delenv("TAA_STUDY_WORKERS", raising=False)
    shape = lambda ex: (ex.kind, ex.workers, ex.worker_threads())     # noqa: E731
    for n, want in ((2, ("auto", 2, 1)), (16, ("auto", 4, 4)), (6, ("auto", 4, 1))):
        monkeypatch.setattr(E, "cores", lambda n=n: n)
        assert shape(_executor(None, None, None)) == want, n
    assert shape(_executor(3, None, None)) == ("local", 3, 2)             # 6 cores shared by 3 workers
    assert _executor(3, 5, None).worker_threads() == 5                     # the user's --threads
    assert _executor(1, None, None).kind == "in-process"                   # --workers 1: debugging
    monkeypatch.setattr(E, "cores", lambda: 1)
    assert _executor(None, None, None).kind == "in-process"
    monkeypatch.setenv("TAA_STUDY_WORKERS", "1")
    monkeypatch.setattr(E, "cores", lambda: 8)
    assert _executor(None, None, None).kind == "in-process"
    monkeypatch.setenv("TAA_STUDY_WORKERS", "two")
    with pytest.raises(SystemExit) as e:
        _executor(None, None, None)
    assert e.value.code == 2

    # a plan under AUTO_MIN_TASKS tasks starts no cluster
    from functools import partial
    from types import SimpleNamespace as NS
    tasks = {f"k{i}": NS(spec=partial(pow, i, 2), deps=(), kind="x") for i in range(E.AUTO_MIN_TASKS - 1)}
    with E.Session(E.Executor("auto", workers=2)) as s:
        got = s.execute(NS(tasks=tasks, cached={"c": 7}), progress=False)
        assert s._client is None
    assert got == {"c": 7, **{f"k{i}": i * i for i in range(E.AUTO_MIN_TASKS - 1)}}
    # nor do references whose file is there (cache hits: an A/B after a study plans dozens)
    hits = {f"r{i}": NS(spec=partial(pow, i, 3), deps=(), kind="reference", likely_cached=True) for i in range(20)}
    with E.Session(E.Executor("auto", workers=2)) as s:
        got = s.execute(NS(tasks={**tasks, **hits}, cached={}), progress=False)
        assert s._client is None and got["r2"] == 8


def test_an_auto_plan_runs_on_a_cluster_whose_workers_have_the_cores_shared_out(tmp_path):
    """Eight tasks on two workers: the cluster is started once for two plans, and each worker's
    Dr.Jit pool has the threads the executor gave it (a worker plugin, set before any task)."""
    code = """
import json, sys
from functools import partial
from types import SimpleNamespace as NS
import drjit as dr
from study.engine import execute as E
E.cores = lambda: 2
# a builtin as the task (a nanobind function has no deterministic Dask token)
plan = lambda tag: NS(tasks={f"{tag}{i}": NS(spec=partial(eval, "__import__('drjit').thread_count()"), deps=(), kind="x") for i in range(E.AUTO_MIN_TASKS)}, cached={})
logged = []
with E.Session(E.Executor("auto", workers=2), log=logged.append) as s:
    a = s.execute(plan("a"), progress=False)
    first = s._client
    b = s.execute(plan("b"), progress=False)
    print(json.dumps({"threads": sorted(set(a.values()) | set(b.values())), "same": s._client is first,
                      "n": len(a) + len(b), "dashboards": sum("dashboard" in m for m in logged)}))
"""
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    got = json.loads(r.stdout.strip().splitlines()[-1])
    assert got == {"threads": [1], "same": True, "n": 2 * 8, "dashboards": 1}, got

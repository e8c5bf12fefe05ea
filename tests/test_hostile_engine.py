"""What a hostile user tries against the engine and the output folder: two columns of one
configuration, a technique's output of the wrong shape or with NaN, EXR I/O on a thread pool, an
interrupted or concurrent report, a full disk. Each ends with a clear message (exit 2) or a
correct study, and leaves the cache and the output folder consistent."""
import os
import sys
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest


# -- EXR I/O on a thread pool ---------------------------------------------------------------------
def test_exr_io_on_a_thread_pool_leaves_stdout_and_fd_2_as_they_were(tmp_path, capfd):
    """The report reads and writes EXR files on a thread pool: the library's stdout and C stderr
    were captured by swapping sys.stdout and fd 2 per call, from several threads at once, and a
    study's tables went into a StringIO that stayed sys.stdout, fd 2 into a deleted file."""
    from references.exr import ExrError, read_exr, write_exr
    img = np.linspace(0, 1, 24 * 32 * 3, dtype=np.float32).reshape(24, 32, 3)
    bad = tmp_path / "bad.exr"
    write_exr(bad, {"RGB": img})
    bad.write_bytes(bad.read_bytes()[: bad.stat().st_size // 2])      # the library prints on both
    stdout, fd2 = sys.stdout, os.fstat(2)

    def work(i):
        path = tmp_path / f"f{i}.exr"
        write_exr(path, {"RGB": img + i})
        got = read_exr(path)[1]
        assert np.array_equal(np.stack([got[c] for c in "RGB"], -1), img + i)
        with pytest.raises(ExrError) as e:
            read_exr(bad)
        assert "Exception raised reading pixel data" in str(e.value), str(e.value)
        return i
    said = []
    with ThreadPoolExecutor(4) as pool:
        futures = [pool.submit(work, i) for i in range(160)]
        for i in range(400):                  # the main thread prints while the pool works
            print(f"line {i}")
            said.append(f"line {i}")
        assert [f.result() for f in futures] == list(range(160))
    assert sys.stdout is stdout
    now = os.fstat(2)
    assert (now.st_dev, now.st_ino) == (fd2.st_dev, fd2.st_ino)
    out, err = capfd.readouterr()
    assert out.splitlines() == said                                    # nothing lost, nothing added
    assert "EXR_ERR" not in err and "Exception raised" not in err      # the library's words: in the messages


# -- two columns of one configuration -------------------------------------------------------------
def test_a_lock_its_thread_holds_is_entered_again_at_once(tmp_path):
    """The metrics task of two identical columns locked one key twice: its own heartbeat kept the
    lock fresh, and the study waited on itself forever."""
    from study.engine.store import Store
    store = Store(tmp_path, log=lambda m: None)
    lock = tmp_path / "locks" / "k.lock"
    done, other = threading.Event(), threading.Event()

    def twice():
        with store.lock("k", stale_s=60, poll_s=0.05):
            with store.lock("k", stale_s=60, poll_s=0.05):
                assert lock.exists()
            assert lock.exists()                       # the inner exit does not release it
            th = threading.Thread(target=lambda: (store.lock("k", poll_s=0.05).__enter__(), other.set()),
                                  daemon=True)
            th.start()                                 # another thread still waits for it
            assert not other.wait(0.5)
        done.set()
    t = threading.Thread(target=twice, daemon=True)
    t.start()
    assert done.wait(10), "the lock's holder waited on itself"
    assert other.wait(10)                              # released once the outer block ended


STUDY = """name = "s"
scenes = ["{scene}"]
resolution = [24, 16]
agreement = false
precision = {{ rule = "per_pixel" }}
{techniques}
[protocols.static]
history = 4
checkpoints = [4]
thesis_history = 4
"""


def _study(tmp_path, techniques: list[str]) -> "os.PathLike":
    from study_fixtures import write_scenes
    _, still = write_scenes(tmp_path)
    path = tmp_path / "s.toml"
    path.write_text(STUDY.format(scene=still, techniques="".join(f'[[techniques]]\nspec = "{t}"\n'
                                                                 for t in techniques)))
    return path


def _cli(tmp_path, args, timeout=300, cache=None):
    import subprocess
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {**os.environ, "TAA_STUDY_CACHE": str(cache or tmp_path / "cache"), "TAA_STUDY_WORKERS": "1"}
    return subprocess.run([sys.executable, "-m", "study", *map(str, args)], capture_output=True, text=True,
                          cwd=root, env=env, timeout=timeout)


@pytest.mark.long(seconds=28)      # with the fixture's study
def test_two_columns_of_one_configuration_are_computed_once_and_both_reported(cached, tmp_path):
    """An A/B of identical configurations is a sanity check: both columns, one run, one metrics
    set, equal figures; and the tables and the summary line reach stdout (the report's thread pool
    left sys.stdout a StringIO)."""
    import csv
    study = _study(tmp_path, ["A=taa_baseline", "B=taa_baseline:sharpen=xu"])
    r = _cli(tmp_path, ["run", study, "--out", tmp_path / "out"], cache=cached[0] / "cache")   # its references
    assert r.returncode == 0, r.stderr[-3000:]
    assert "Traceback" not in r.stderr
    assert "| scene | protocol | A | B |" in r.stdout and "runs computed 1, cached 1; metrics computed 1" in r.stdout
    head = list(csv.reader((tmp_path / "out" / "tables" / "headline.csv").read_text().splitlines()))
    assert head[0][2:4] == ["A", "B"] and len(head) == 2, head
    assert all(row[2] == row[3] for row in head[1:]), head          # one run: the same figures


# -- a technique's output -------------------------------------------------------------------------
BAD_TECHNIQUE = """import numpy as np
from taa_impl.simple import NoAA


class Bad(NoAA):
    name = "bad"

    def process(self, frame, **kw):
        h, w = frame["color"].shape[:2]
        return {out}
"""


@pytest.mark.parametrize("out, words", [
    ("np.zeros((h, w, 2), np.float32)", "returned an image of shape (16, 24, 2), expected (16, 24, 3)"),
    ("np.zeros((h - 1, w, 3), np.float32)", "returned an image of shape (15, 24, 3), expected (16, 24, 3)"),
    ("np.full((h, w, 3), np.nan, np.float32)", "technique 'X' produced NaN/Inf in 1152 of 1152 values"),
    ("'not an image'", "returned str, not an image"),
])
def test_the_driver_checks_a_technique_output_against_its_declared_size(tmp_path, out, words):
    """An (H, W, 2) image was written past its end and the study exited 0; an (H - 1, W, 3) one was
    sealed in the cache and failed in the metrics naming nothing; NaN named no file or class."""
    from study.config.protocols import static_schedule
    from study.config.techniques import TechniqueConfig
    from study.engine.drive import TechniqueError, run_schedule
    from study.engine.tasks import load_scene
    from study_fixtures import write_scenes
    (tmp_path / "bad_taa.py").write_text(BAD_TECHNIQUE.format(out=out))
    _, still = write_scenes(tmp_path)
    cfg = TechniqueConfig.parse(f"X={tmp_path / 'bad_taa.py'}:Bad")
    emitted = []
    with pytest.raises(TechniqueError) as e:
        run_schedule(load_scene(still), 24, 16, static_schedule(0, 4, [4]), [cfg], {}, progress=False,
                     emit=lambda *a: emitted.append(a))
    for w in (words, "technique 'X'", f"{tmp_path / 'bad_taa.py'}:Bad", "scene 'tiny_still', frame 4"):
        assert w in str(e.value), (w, str(e.value))
    assert emitted == []                                               # nothing reached the cache


@pytest.mark.long(seconds=8)
def test_a_bad_output_stops_the_study_before_anything_is_sealed(tmp_path):
    """The study exits 2 with the driver's message, seals no run and makes no output folder."""
    (tmp_path / "bad_taa.py").write_text(BAD_TECHNIQUE.format(out="np.zeros((h, w, 2), np.float32)"))
    study = _study(tmp_path, [f"X={tmp_path / 'bad_taa.py'}:Bad"])
    r = _cli(tmp_path, ["run", study, "--out", tmp_path / "out"])
    assert r.returncode == 2, r.stderr[-3000:]
    assert "Traceback" not in r.stderr
    (err,) = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    for w in ("returned an image of shape (16, 24, 2), expected (16, 24, 3)", "technique 'X'",
              f"{tmp_path / 'bad_taa.py'}:Bad", "scene 'tiny_still'", "frame 4"):
        assert w in err, (w, err)
    assert not list((tmp_path / "cache" / "runs").rglob("done.json"))      # nothing sealed
    assert not (tmp_path / "out").exists()                           # no empty output folder either


# -- the output folder ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def cached(tmp_path_factory):
    """A tiny study's cache, computed once: the tests below only write its report."""
    root = tmp_path_factory.mktemp("cached")
    study = _study(root, ["A=noaa"])
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("TAA_STUDY_PLOTS", "0")          # its own report is read by none (the tests' draw theirs)
        r = _cli(root, ["run", study, "--out", root / "first"])
    assert r.returncode == 0, r.stderr[-3000:]
    return root, study


def _run_in_process(root, study, out, monkeypatch):
    from click.testing import CliRunner
    from study.commands.cli import main
    monkeypatch.setenv("TAA_STUDY_CACHE", str(root / "cache"))
    return CliRunner().invoke(main, ["run", str(study), "--out", str(out)])


def _leftovers(out):
    return sorted(p.name for p in out.parent.iterdir() if p.name.startswith(f".{out.name}."))


@pytest.mark.long(seconds=14)
def test_an_interrupted_first_report_leaves_nothing_the_rerun_refuses(cached, tmp_path, monkeypatch):
    """SIGTERM while the first report was written left tables and images without manifest.json,
    and the next run refused the folder as someone else's."""
    import signal
    import subprocess
    root, study = cached
    out = tmp_path / "out"
    code = ("import os, signal, sys\nimport study.reporting.report as R\n"
            "real = R.Report.finish\n"
            "def finish(self, summary):\n    os.kill(os.getpid(), signal.SIGTERM)\n"
            "R.Report.finish = finish\nfrom study.commands.cli import main\n"
            f"main(['run', {str(study)!r}, '--out', {str(out)!r}])\n")
    env = {**os.environ, "TAA_STUDY_CACHE": str(root / "cache"), "TAA_STUDY_WORKERS": "1"}
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300,
                       cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    assert p.returncode == -signal.SIGTERM, p.stderr[-3000:]
    assert not out.exists()                                            # half a report is not the folder
    r = _run_in_process(root, study, out, monkeypatch)
    assert r.exit_code == 0, r.output
    assert (out / "manifest.json").is_file() and (out / "tables" / "headline.csv").is_file()
    assert _leftovers(out) == []                                       # no staging folder, no lock

    # Ctrl-C in this process, while the first report is written: nothing left either
    import study.reporting.report as R

    def interrupted(self, summary):
        raise KeyboardInterrupt
    out3 = tmp_path / "out3"
    with monkeypatch.context() as mp:
        mp.setattr(R.Report, "finish", interrupted)
        r = _run_in_process(root, study, out3, monkeypatch)
    assert r.exit_code != 0 and not out3.exists() and _leftovers(out3) == [], r.output

    # a first report interrupted while it was moved into an existing (empty) folder
    out2 = tmp_path / "out2"
    (out2 / "tables").mkdir(parents=True)
    (out2 / "tables" / "half.csv").write_text("x")
    (out2 / ".taa-study-incomplete").write_text("")
    r = _run_in_process(root, study, out2, monkeypatch)
    assert r.exit_code == 0, r.output
    assert (out2 / "manifest.json").is_file() and not (out2 / "tables" / "half.csv").exists()
    assert not (out2 / ".taa-study-incomplete").exists()


@pytest.mark.long(seconds=1)
def test_a_full_disk_while_writing_the_report_exits_2_and_keeps_the_folder_whole(cached, tmp_path, monkeypatch):
    """ENOSPC in the output folder was a traceback with exit 1."""
    import errno

    import provenance.files as PF
    import study.engine.store  # noqa: F401  (imported under the patch, it would keep the full disk's writer)
    import study.reporting.report as R
    root, study = cached
    out = tmp_path / "out"
    real = PF.write_bytes_atomic
    calls = []

    def full(path, data):
        calls.append(path)
        if len(calls) > 3:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        return real(path, data)
    with monkeypatch.context() as mp:
        mp.setattr(PF, "write_bytes_atomic", full)
        mp.setattr(R, "write_bytes_atomic", full)
        r = _run_in_process(root, study, out, monkeypatch)
    assert r.exit_code == 2, r.output
    assert "Traceback" not in r.output
    (err,) = [line for line in r.output.splitlines() if line.startswith("error:")]
    assert f"--out {out}: cannot write the report (" in err and "No space left on device" in err, err
    assert "MB free on its disk); nothing was written" in err, err
    assert not out.exists() and _leftovers(out) == []

    # a second report: the first one's manifest stands, and lists files that are all there
    assert _run_in_process(root, study, out, monkeypatch).exit_code == 0
    manifest = (out / "manifest.json").read_bytes()
    calls.clear()
    with monkeypatch.context() as mp:
        (out / "tables" / "headline.csv").unlink()                      # something to write again
        calls.extend([None] * 4)                                         # full from the first write
        mp.setattr(PF, "write_bytes_atomic", full)
        mp.setattr(R, "write_bytes_atomic", full)
        r = _run_in_process(root, study, out, monkeypatch)
    assert r.exit_code == 2 and "its previous report's manifest still stands" in r.output, r.output
    assert (out / "manifest.json").read_bytes() == manifest and _leftovers(out) == []


def test_a_second_study_on_a_folder_another_is_writing_exits_2_naming_both(tmp_path, monkeypatch):
    """Two studies into one --out at once both exited 0, one's manifest beside the other's tables."""
    import socket
    out = tmp_path / "out"
    lock = tmp_path / ".out.taa-study-lock"
    lock.write_text(f"{socket.gethostname()} {os.getppid()} 1")        # a live process of this host
    study = _study(tmp_path, ["A=noaa"])
    r = _run_in_process(tmp_path, study, out, monkeypatch)
    assert r.exit_code == 2, r.output
    assert (f"--out {out}: another study is writing this folder (process {os.getppid()} on host "
            f"{socket.gethostname()}") in r.output, r.output
    assert not out.exists() and not (tmp_path / "cache").exists()      # refused before any work
    assert lock.read_text().split()[1] == str(os.getppid())            # the other's lock stays


def test_a_full_cache_disk_mid_study_exits_2_and_the_same_command_goes_on(tmp_path, monkeypatch):
    """ENOSPC writing a task's record in the cache ended in an OSError traceback, exit 1."""
    import errno

    import study.engine.store as S
    study = _study(tmp_path, ["A=noaa"])
    out = tmp_path / "out"
    real = S.write_text_atomic

    def full(path, text):
        if Path(path).name == "done.json" and "/runs/" in str(path):    # the run's record, after its reference
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        return real(path, text)
    with monkeypatch.context() as mp:
        mp.setattr(S, "write_text_atomic", full)
        r = _run_in_process(tmp_path, study, out, monkeypatch)
    assert r.exit_code == 2, (r.output, r.exc_info)
    assert "Traceback" not in r.output
    (err,) = [line for line in r.output.splitlines() if line.startswith("error:")]
    assert f"the study cache {tmp_path / 'cache'}: cannot write (done.json: No space left on device: " in err, err
    assert "MB free on its disk); the tasks finished so far stay cached" in err, err
    assert not out.exists() and _leftovers(out) == []
    r = _run_in_process(tmp_path, study, out, monkeypatch)              # room again: it goes on
    assert r.exit_code == 0, r.output
    assert "runs computed 1, cached 0" in r.output and "references rendered 0" in r.output, r.output


# -- figures and the disk -------------------------------------------------------------------------
def test_figures_json_is_strict_and_keeps_an_infinite_figure(tmp_path):
    """An exact image's PSNR is +inf: figures.json held a bare Infinity, which no strict JSON
    parser (a browser's JSON.parse, jq) reads."""
    import json
    import math
    from types import SimpleNamespace

    from study.reporting.encode import from_strict
    from study.reporting.report import Report
    r = SimpleNamespace(scene="s", width=4, height=2, reference_bound_lsb=0.5, artefacts={"A": {"metrics_key": "k"}},
                        per_frame={"A": {3: {"psnr": math.inf, "mse": 0.0, "ssim": 1.0, "relmse_hdr": math.nan}}},
                        uncertainty={"A": {3: {"psnr": math.inf}}}, temporal={"A": -math.inf}, temporal_u={},
                        jod={}, jod_u={})
    res = SimpleNamespace(statics=[r], ghosts={}, sweeps=[], tolerances={"psnr_db": 0.05}, precision={})
    rep = Report(tmp_path)
    rep.precision(res)
    text = (tmp_path / "tables" / "figures.json").read_text()
    doc = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-strict JSON constant {c}"))
    got = from_strict(doc)["tests"][0]["techniques"]["A"]
    assert got["frames"]["3"]["figures"] == {"psnr": math.inf, "mse": 0.0, "ssim": 1.0, "relmse_hdr": None}
    assert got["frames"]["3"]["uncertainty"]["psnr"] == math.inf and got["temporal"] == -math.inf


def test_no_column_is_best_among_equals():
    """Every column at PSNR ∞ (or two identical configurations): 'best' named the first column."""
    import math

    from study.reporting.tables import best_of, thesis_layout
    assert best_of("psnr", {"A": math.inf, "B": math.inf}) == "all tied"
    assert best_of("psnr", {"A": 30.0, "B": 31.0, "C": 31.0}) == "B = C"
    assert best_of("mse", {"A": 2.0, "B": 1.0, "C": None}) == "B"
    assert best_of("psnr", {"A": math.nan, "B": None}) is None
    t = thesis_layout("t", {"A": {"psnr": math.inf, "ms": 1.0}, "Improved": {"psnr": math.inf, "ms": 2.0}},
                      ["psnr", "ms"], "Improved")
    assert t.rows == [["PSNR (dB)", "∞", "∞", "all tied", "best"], ["ms / frame", "1.00", "2.00", "A", "+1"]]


def test_the_spare_disk_margin_scales_with_the_study():
    """A fixed 2 GB margin refused a 250 KB study on a disk with 1 GB free."""
    from pathlib import Path

    from study.engine import disk as D
    tiny = {"references": 150_000, "maps": 50_000, "tests": {("s", "static"): (50_000, 50_000)}, "run": 0}
    assert D.margin(tiny) == 64 * 2 ** 20
    assert D.fit(tiny, 2 ** 30, False, Path("/c")) == {("s", "static")}            # 1 GB free: it fits
    with pytest.raises(D.DiskError) as e:
        D.fit(tiny, 10 * 2 ** 20, False, Path("/c"))
    assert ("the study needs about 64.2 MB in the cache folder /c (references 146.5 KB, the runs' kept frames and "
            "maps 97.7 KB, 4 runs being judged 0.0 KB, 64.0 MB spare: 25% of these, 64.0 MB to 2.0 GB) and "
            "10.0 MB is free") in str(e.value), str(e.value)
    big = {"references": 40 * 2 ** 30, "maps": 0, "tests": {}, "run": 0}
    assert D.margin(big) == 2 * 2 ** 30


def test_a_first_report_never_clears_files_that_appeared_meanwhile(tmp_path):
    """A folder someone filled while the study ran is not the empty folder the study was given."""
    from study.commands.out_folder import OutFolder, OutFolderError
    out = tmp_path / "o"
    with OutFolder(out) as folder:
        out.mkdir()
        (out / "mine.txt").write_text("x")
        with pytest.raises(OutFolderError, match="files appeared in the folder while the study ran"):
            folder.write(lambda where: (where / "manifest.json").write_text("{}"))
    assert sorted(p.name for p in out.iterdir()) == ["mine.txt"] and sorted(p.name for p in tmp_path.iterdir()) == ["o"]


NAN_AT_SECOND = """import numpy as np
from taa_impl.baseline import BaselineTAA


class NaNOnce(BaselineTAA):
    calls = 0

    def process(self, frame, **kw):
        out = np.array(super().process(frame, **kw))
        NaNOnce.calls += 1
        if NaNOnce.calls == 2:
            out[0, 0, 1] = np.nan
        return out
"""


def test_a_nan_between_judged_frames_is_refused_on_the_frame_that_made_it(tmp_path):
    """A technique with history is judged at frame 4 only; a NaN it makes at frame 2 would reach
    every later frame through its history: refused at frame 2, naming the column and its class."""
    from study.config.protocols import static_schedule
    from study.config.techniques import TechniqueConfig
    from study.engine.drive import TechniqueError, run_schedule
    from study.engine.tasks import load_scene
    from study_fixtures import write_scenes
    (tmp_path / "nan_taa.py").write_text(NAN_AT_SECOND)
    _, still = write_scenes(tmp_path)
    cfg = TechniqueConfig.parse(f"X={tmp_path / 'nan_taa.py'}:NaNOnce")
    with pytest.raises(TechniqueError) as e:
        run_schedule(load_scene(still), 24, 16, static_schedule(0, 4, [4]), [cfg], {}, progress=False,
                     emit=lambda *a: None)
    for w in ("technique 'X' produced NaN/Inf in 1 of 1152 values", f"{tmp_path / 'nan_taa.py'}:NaNOnce",
              "frame 2"):
        assert w in str(e.value), (w, str(e.value))

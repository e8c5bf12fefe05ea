"""What a hostile user tries against the engine and the output folder: two columns of one
configuration, a technique's output of the wrong shape or with NaN, EXR I/O on a thread pool, an
interrupted or concurrent report, a full disk. Each ends with a clear message (exit 2) or a
correct study, and leaves the cache and the output folder consistent."""
import os
import sys
import threading
from concurrent.futures import ThreadPoolExecutor

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
        path = tmp_path / f"f{i % 8}.exr"
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


def _cli(tmp_path, args, timeout=300):
    import subprocess
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {**os.environ, "TAA_STUDY_CACHE": str(tmp_path / "cache"), "TAA_STUDY_WORKERS": "1"}
    return subprocess.run([sys.executable, "-m", "study", *map(str, args)], capture_output=True, text=True,
                          cwd=root, env=env, timeout=timeout)


@pytest.mark.long(seconds=12)
def test_two_columns_of_one_configuration_are_computed_once_and_both_reported(tmp_path):
    """An A/B of identical configurations is a sanity check: both columns, one run, one metrics
    set, equal figures; and the tables and the summary line reach stdout (the report's thread pool
    left sys.stdout a StringIO)."""
    import csv
    study = _study(tmp_path, ["A=taa_baseline", "B=taa_baseline:sharpen=xu"])
    r = _cli(tmp_path, ["run", study, "--out", tmp_path / "out"])
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


@pytest.mark.long(seconds=8)
@pytest.mark.parametrize("out, words", [
    ("np.zeros((h, w, 2), np.float32)", ["returned an image of shape (16, 24, 2), expected (16, 24, 3)"]),
    ("np.zeros((h - 1, w, 3), np.float32)", ["returned an image of shape (15, 24, 3), expected (16, 24, 3)"]),
    ("np.full((h, w, 3), np.nan, np.float32)", ["technique 'X' produced NaN/Inf in 1152 of 1152 values"]),
])
def test_a_bad_output_is_refused_before_it_is_stored(tmp_path, out, words):
    """An (H, W, 2) image was written past its end and the study exited 0; an (H - 1, W, 3) one was
    sealed in the cache and failed in the metrics naming nothing; NaN named no file or class."""
    (tmp_path / "bad_taa.py").write_text(BAD_TECHNIQUE.format(out=out))
    study = _study(tmp_path, [f"X={tmp_path / 'bad_taa.py'}:Bad"])
    r = _cli(tmp_path, ["run", study, "--out", tmp_path / "out"])
    assert r.returncode == 2, r.stderr[-3000:]
    assert "Traceback" not in r.stderr
    (err,) = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    for w in words + ["technique 'X'", f"{tmp_path / 'bad_taa.py'}:Bad", "scene 'tiny_still'", "frame 4"]:
        assert w in err, (w, err)
    assert not list((tmp_path / "cache" / "runs").rglob("done.json"))      # nothing sealed
    assert not (tmp_path / "out").exists()                           # no empty output folder either

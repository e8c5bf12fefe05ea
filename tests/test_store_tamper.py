"""Tamper-evident store, complete keys and output hygiene: an edited, corrupted or
swapped artefact is reported and re-made, never reaching a table; a subset run leaves no table of
an earlier, larger one; files get the user's umask."""
import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from study_fixtures import run_cli, summary, write_scenes


@pytest.fixture
def study(tmp_path, monkeypatch, no_plots):         # the tampering tests read tables, not plots
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    moving, still = write_scenes(tmp_path)
    args = ["run", "--scenes", still, "--no-agreement", "--precision", "per_pixel", "--out", tmp_path / "out",
            "--techniques", "Baseline=taa_baseline", "--techniques", "FXAA=fxaa"]
    run_cli(args)
    return tmp_path, args


def _headline_psnr(out, label):
    rows = (out / "tables" / "headline.csv").read_text().splitlines()
    head = rows[0].split(",")
    return [r.split(",")[head.index(label)] for r in rows[1:]]


def test_edited_metrics_never_reach_a_table(study):
    tmp, args = study
    before = _headline_psnr(tmp / "out", "Baseline")
    done = next(p for p in (tmp / "cache" / "metrics").rglob("done.json") if '"psnr"' in p.read_text()
                and json.loads(p.read_text())["data"]["per_frame"].get("256"))
    rec = json.loads(done.read_text())
    rec["data"]["per_frame"]["256"]["psnr"] = 44.444          # key kept, value edited
    done.write_text(json.dumps(rec))
    err = run_cli(args).stderr
    assert "content hash" in err and str(done.parent) in err
    assert not any("44.444" in c for c in _headline_psnr(tmp / "out", "Baseline"))
    assert _headline_psnr(tmp / "out", "Baseline") == before
    assert summary(tmp / "out")["metrics_computed"] == 1


def test_garbage_maps_and_a_swapped_frame_are_detected_and_re_made(study):
    tmp, args = study
    maps = next((tmp / "cache" / "metrics").rglob("maps_0256.exr"))
    maps.write_bytes(b"garbage" * 100)
    # the frame the report shows, kept by the metrics record (its run keeps none: study.engine.judge)
    other = maps.parent / "shown_0256.png"
    shown = next(p for p in (tmp / "cache" / "metrics").rglob("shown_0256.png") if p.parent != maps.parent)
    assert shown.read_bytes() != other.read_bytes()
    shown.write_bytes(other.read_bytes())                      # a valid PNG, the other technique's
    err = run_cli(args).stderr
    assert f"{maps}: expected SHA-256" in err and f"{shown}: expected SHA-256" in err
    s = summary(tmp / "out")
    # each judged again, from its run made again (a run pruned once judged keeps no frame)
    assert s["runs_computed"] == 2 and s["metrics_computed"] == 2
    run_cli(args)                                               # all intact again
    s = summary(tmp / "out")
    assert s["runs_computed"] == 0 and s["metrics_computed"] == 0


def test_a_subset_run_leaves_no_table_of_the_first(tmp_path, monkeypatch):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    moving, still = write_scenes(tmp_path)
    base = ["run", "--no-agreement", "--precision", "per_pixel", "--out", tmp_path / "out", "--techniques", "noaa"]
    run_cli(base + ["--scenes", f"{moving},{still}"])
    assert (tmp_path / "out" / "tables" / "ghosting_tiny_moving.md").exists()
    run_cli(base + ["--scenes", still])
    tables = sorted(p.name for p in (tmp_path / "out" / "tables").iterdir())
    assert not [t for t in tables if "tiny_moving" in t]
    listed = json.loads((tmp_path / "out" / "manifest.json").read_text())["artefacts"]
    on_disk = {str(p.relative_to(tmp_path / "out")) for f in ("tables", "images", "maps", "plots")
               for p in (tmp_path / "out" / f).rglob("*") if p.is_file()}
    assert on_disk == {k for k in listed if k.split("/")[0] in ("tables", "images", "maps", "plots")}


def test_files_get_the_users_umask(tmp_path):
    code = ("import os, sys; os.umask(0o022); sys.path.insert(0, 'tests');"
            "from pathlib import Path; from study.engine.store import Store, write_text_atomic; import numpy as np;"
            f"root = Path({str(tmp_path)!r});"
            "write_text_atomic(root / 'a.txt', 'x');"
            "Store(root).save_folder(root / 'f', 'k', {'frame_0001.exr': np.zeros((2, 2, 3), np.float32)}, {})")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=Path(__file__).parent.parent)
    for p in (tmp_path / "a.txt", tmp_path / "f" / "frame_0001.exr", tmp_path / "f" / "done.json"):
        assert stat.S_IMODE(os.stat(p).st_mode) == 0o644, p


def test_a_technique_in_the_users_own_file_is_keyed_by_its_source(tmp_path, monkeypatch):
    import importlib
    from provenance import code_token
    mod = tmp_path / "my_taa_mod.py"
    mod.write_text("from taa_impl.baseline import BaselineTAA\nclass MyTAA(BaselineTAA):\n    name = 'my'\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    m = importlib.import_module("my_taa_mod")
    k1 = code_token(m.MyTAA)
    assert k1 != code_token(importlib.import_module("taa_impl.baseline").BaselineTAA)
    mod.write_text(mod.read_text() + "# edited\n")
    os.utime(mod, ns=(os.stat(mod).st_atime_ns, os.stat(mod).st_mtime_ns + 10**9))
    assert code_token(m.MyTAA) != k1


def test_a_crash_while_writing_an_artefact_leaves_no_done_record(tmp_path, monkeypatch):
    # the done record is written last: a crash between two files leaves a folder the store calls
    # incomplete (re-made), never a record naming files that were not written
    import numpy as np

    from study.engine import store as S
    st = S.Store(tmp_path)
    img = np.zeros((2, 3, 3), np.float32)
    calls = []

    def failing(path, channels, header=None, **kw):
        calls.append(path)
        if len(calls) == 2:
            raise OSError("disk full")
        return real(path, channels, header)
    real = S.write_exr
    monkeypatch.setattr(S, "write_exr", failing)
    folder = tmp_path / "runs" / "static" / "s" / "k"
    with pytest.raises(OSError, match="disk full"):
        st.save_folder(folder, "k", {"frame_0001.exr": img, "frame_0002.exr": img}, {"frames": [1, 2]})
    assert not (folder / "done.json").exists() and st.done(folder, "k") is None
    monkeypatch.setattr(S, "write_exr", real)
    rec = st.save_folder(folder, "k", {"frame_0001.exr": img, "frame_0002.exr": img}, {"frames": [1, 2]})
    assert st.done(folder, "k", verify_files=True) == rec and sorted(rec["files"]) == ["frame_0001.exr",
                                                                                       "frame_0002.exr"]


def test_remembered_hashes_still_catch_an_edit_that_restores_the_modification_time(tmp_path, monkeypatch):
    """A file's hash is remembered with its state, so a second check reads no file; an edit of the
    same size with its modification time set back is still found (the change time moved), and a
    file changed within the last 2 s is not remembered."""
    import time

    import numpy as np

    from study.engine import store as S
    calls = []
    real = S.sha256_file
    monkeypatch.setattr(S, "sha256_file", lambda p: calls.append(p) or real(p))
    monkeypatch.setattr(S, "_HASHES", {})
    store = S.Store(tmp_path)
    folder = tmp_path / "runs" / "x"
    rec = store.save_folder(folder, "k", {"frame_0000.exr": np.full((4, 4, 3), 0.5, np.float32)}, {})
    calls.clear()
    assert store.done(folder, "k", verify_files=True) is not None
    assert len(calls) == 1                       # just written: hashed, not remembered
    monkeypatch.setattr(S, "_SETTLE_NS", 0)
    store.done(folder, "k", verify_files=True)
    store.save_hashes()
    monkeypatch.setattr(S, "_HASHES", {})        # a new process: the hashes come from the cache's file
    calls.clear()
    assert S.Store(tmp_path).done(folder, "k", verify_files=True) is not None and calls == []
    path = folder / "frame_0000.exr"
    st = path.stat()
    data = bytearray(path.read_bytes())
    data[-1] ^= 0xFF                             # same size, other content
    time.sleep(0.01)
    path.write_bytes(bytes(data))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert path.stat().st_mtime_ns == st.st_mtime_ns and path.stat().st_size == st.st_size
    logs = []
    assert S.Store(tmp_path, log=logs.append).done(folder, "k", verify_files=True) is None
    assert len(calls) == 1 and "expected SHA-256" in logs[0] and rec["files"]["frame_0000.exr"][:16] in logs[0]


def test_a_remembered_done_record_is_read_once_and_an_edit_is_still_caught(tmp_path, monkeypatch):
    """Store.done remembers an unsealed record with its file's state (a study plans twice and its
    report reads the records again); any write changes that state, so an edit made after the
    record was remembered is still caught."""
    import time as _time
    from study.engine import store as S
    st = S.Store(tmp_path)
    folder = tmp_path / "runs" / "x"
    st.save_folder(folder, "k1", {"frame_0000.exr": np.zeros((2, 2, 3), np.float32)}, {"label": "A"})
    monkeypatch.setattr(S, "_SETTLE_NS", 0)           # remembered at once (else after 2 s)
    reads = []
    real = Path.read_text
    monkeypatch.setattr(Path, "read_text", lambda self, *a, **k: reads.append(self.name) or real(self, *a, **k))
    assert st.done(folder, "k1")["label"] == "A"
    assert st.done(folder, "k1")["label"] == "A"
    assert reads.count("done.json") == 1
    _time.sleep(0.01)
    text = real(folder / "done.json")
    (folder / "done.json").write_text(text.replace('"A"', '"B"'))    # key kept, value edited
    assert st.done(folder, "k1") is None                               # the seal no longer matches
    assert reads.count("done.json") == 2

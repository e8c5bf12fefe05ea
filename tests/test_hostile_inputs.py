"""Inputs a hostile or careless user gives: each is refused with exit status 2 (or its library
exception) naming the file, field, value or address, without a traceback, without reading or
writing outside what it names, and without leaving an output folder behind."""
import hashlib
import json
import os

import pytest
from click.testing import CliRunner

from scenes import SceneError
from scenes.loader import load_scene_file
from study.commands.cli import main
from test_gltf_scene import _hand_gltf, scene_file

SECRET = b"QZ-not-for-the-message-QZ"


def _gltf_with(tmp_path, edit):
    """hand.gltf in tmp/scene/ after `edit(doc)`; a secret file and a copy of its buffer beside
    the folder (outside it)."""
    folder = tmp_path / "scene"
    folder.mkdir()
    doc = _hand_gltf(folder)
    (tmp_path / "outside.bin").write_bytes((folder / "hand.bin").read_bytes())
    (tmp_path / "secret.txt").write_bytes(SECRET * 4)
    edit(doc, folder)
    (folder / "hand.gltf").write_text(json.dumps(doc))
    return scene_file(folder, path="hand.gltf")


def _set_buffer_uri(uri):
    def edit(doc, folder):
        doc["buffers"][0]["uri"] = uri(folder) if callable(uri) else uri
    return edit


def _set_image_uri(uri):
    def edit(doc, folder):
        doc["images"][0]["uri"] = uri(folder) if callable(uri) else uri
    return edit


def _symlink(name, target):
    def make(folder):
        os.symlink(target(folder) if callable(target) else target, folder / name)
        return name
    return make


@pytest.mark.parametrize("edit, words", [
    (_set_buffer_uri("../outside.bin"), ["buffers[0].uri", "'../outside.bin' resolves outside the glTF file's folder"]),
    (_set_buffer_uri("%2e%2e/outside.bin"), ["buffers[0].uri", "'%2e%2e/outside.bin' resolves outside"]),
    (_set_buffer_uri(lambda f: str(f.parent / "outside.bin")), ["buffers[0].uri", "absolute paths are not read"]),
    (_set_buffer_uri(lambda f: "file://" + str(f.parent / "outside.bin")), ["URI scheme 'file' is not read"]),
    (_set_buffer_uri(_symlink("link.bin", lambda f: f.parent / "outside.bin")), ["'link.bin' resolves outside"]),
    (_set_buffer_uri(_symlink("zero.bin", "/dev/zero")), ["'zero.bin' resolves outside"]),
    (_set_image_uri("../secret.txt"), ["images[0].uri", "'../secret.txt' resolves outside"]),
    (_set_image_uri(lambda f: str(f.parent / "secret.txt")), ["images[0].uri", "absolute paths are not read"]),
    (_set_buffer_uri("http://example.invalid/hand.bin"),
     ["buffers[0].uri: remote URIs are not fetched: http://example.invalid/hand.bin"]),
    (_set_image_uri("https://example.invalid/t.png"), ["images[0].uri: remote URIs are not fetched: https://"]),
])
def test_gltf_uris_stay_inside_the_scene_folder(tmp_path, edit, words):
    f = _gltf_with(tmp_path, edit)
    with pytest.raises(SceneError) as err:
        load_scene_file(f)
    msg = str(err.value)
    for w in words:
        assert w in msg, (w, msg)
    assert "hand.gltf" in msg and "file not found" not in msg, msg
    assert SECRET[:6].decode() not in msg and "QZ" not in msg, msg      # nothing of the file quoted
    r = CliRunner().invoke(main, ["agree", "--scene", f])
    assert r.exit_code == 2 and words[-1] in r.output and "Traceback" not in r.output, r.output


def test_gltf_uri_that_is_not_a_regular_file(tmp_path):
    def edit(doc, folder):
        os.mkfifo(folder / "pipe.bin")      # opening it for reading would wait for a writer forever
        doc["buffers"][0]["uri"] = "pipe.bin"
    with pytest.raises(SceneError) as err:
        load_scene_file(_gltf_with(tmp_path, edit))
    assert "buffers[0].uri" in str(err.value) and "pipe.bin is not a regular file" in str(err.value)


def test_gltf_buffer_is_read_to_its_byte_length_only(tmp_path):
    def pad(doc, folder):
        data = (folder / "hand.bin").read_bytes()
        (folder / "hand.bin").write_bytes(data + b"\x00" * 4096)   # padded past byteLength
    f = _gltf_with(tmp_path, pad)
    s = load_scene_file(f)
    data = (tmp_path / "outside.bin").read_bytes()                  # the unpadded buffer
    assert hashlib.sha256(data).hexdigest() in s.asset_digests
    for bad in (10 ** 15, 0, -4, 2.5, "12"):
        def edit(doc, folder, bad=bad):
            doc["buffers"][0]["byteLength"] = bad
        (tmp_path / "b").mkdir()
        with pytest.raises(SceneError) as err:
            load_scene_file(_gltf_with(tmp_path / "b", edit))
        assert f"buffers[0].byteLength: must be a whole number in 1..{2 ** 31}, got {bad!r}" in str(err.value)
        import shutil
        shutil.rmtree(tmp_path / "b")


def test_gltf_image_file_size_is_capped(tmp_path, monkeypatch):
    import scenes.gltf_container as gc
    monkeypatch.setattr(gc, "MAX_IMAGE_BYTES", 64)   # the real cap is 256 MiB: too large to write here

    def edit(doc, folder):
        (folder / "big.png").write_bytes(b"\x89PNG" + b"\x00" * 200)
        doc["images"][0]["uri"] = "big.png"
    with pytest.raises(SceneError) as err:
        load_scene_file(_gltf_with(tmp_path, edit))
    assert "images[0].uri" in str(err.value) and "big.png has 204 bytes, more than the 64" in str(err.value)


def _cli(args, **env):
    import subprocess
    import sys
    return subprocess.run([sys.executable, "-m", "study", *args], capture_output=True, text=True, timeout=120,
                          env={**os.environ, **env})


@pytest.mark.parametrize("variant, words", [
    ("nosuch", ["TAA_VARIANT='nosuch' is not a variant this project runs", "llvm_ad_rgb", "cuda_ad_rgb"]),
    ("scalar_rgb", ["TAA_VARIANT='scalar_rgb' is not a variant this project runs", "llvm_ad_rgb"]),
    ("llvm_ad_spectral", ["TAA_VARIANT='llvm_ad_spectral' is not a variant"]),
    ("cuda_ad_rgb", ["TAA_VARIANT='cuda_ad_rgb': no CUDA device was found"]),
])
def test_an_unsupported_taa_variant_exits_2_naming_it(variant, words):
    from backend import dr
    if variant.startswith("cuda") and dr.has_backend(dr.JitBackend.CUDA):
        pytest.skip("this machine has a CUDA device")
    r = _cli(["scenes"], TAA_VARIANT=variant)
    assert r.returncode == 2, (r.returncode, r.stderr[-2000:])
    for w in words:
        assert w in r.stderr, (w, r.stderr)
    assert "Traceback" not in r.stderr and r.stdout == "", r.stderr


@pytest.mark.long(60)
def test_bench_as_the_readme_gives_it_times_every_technique_upscalers_at_their_scales():
    """`taa-study bench` without --technique (the README's speed command) at a tiny size: every
    registered technique has an entry, each upscaler one per render scale, all finite times."""
    import math

    import taa_impl
    r = CliRunner().invoke(main, ["bench", "--width", "48", "--height", "27", "--repeats", "1",
                                  "--render-scale", "0.5,1", "--json"])
    assert r.exit_code == 0, r.output[-3000:]
    res = json.loads(r.stdout)
    want = []
    for name in taa_impl.TECHNIQUES:
        if getattr(taa_impl.make(name), "upsamples", False):
            want += [f"{name} ×0.5", f"{name} ×1"]
        else:
            want.append(name)
    assert list(res["techniques"]) == want
    assert {"fsr2 ×0.5", "taau ×1", "upscale_spatial ×0.5"} <= set(want)
    for name in want:
        ms = res["techniques"][name]["ms"]
        assert math.isfinite(ms) and ms > 0 and math.isfinite(res["bandwidth_floor_ms"][name]), name
    # an upscaler at 0.5 reads a quarter of the inputs it reads at 1
    assert res["bandwidth_floor_ms"]["fsr2 ×0.5"] < res["bandwidth_floor_ms"]["fsr2 ×1"]


def _listener(reply: bytes | None):
    """A one-connection TCP listener on 127.0.0.1 (not Dask) that sends `reply` (None: nothing)
    and closes; it stops by itself after 20 s. Returns its port."""
    import socket
    import threading
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)
    srv.settimeout(20)

    def serve():
        try:
            conn, _ = srv.accept()
            with conn:
                if reply is not None:
                    conn.sendall(reply)
                conn.settimeout(3)
                try:
                    conn.recv(1024)
                except OSError:
                    pass
        except OSError:
            pass
        finally:
            srv.close()
    threading.Thread(target=serve, daemon=True).start()
    return srv.getsockname()[1]


def _closed_port():
    import socket
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()                      # nothing listens there now
    return port


@pytest.mark.parametrize("address, words", [
    ("127.0.0.1:8786", ["not an address of the form tcp://HOST:PORT"]),
    ("tcp://127.0.0.1", ["not an address of the form tcp://HOST:PORT"]),
    ("tcp://127.0.0.1:99999", ["not an address of the form tcp://HOST:PORT"]),
    ("http://127.0.0.1:8786", ["not an address of the form tcp://HOST:PORT"]),
    (lambda: f"tcp://127.0.0.1:{_closed_port()}", ["cannot connect (Connection refused)"]),
    (lambda: f"tcp://127.0.0.1:{_listener(b'HTTP/1.1 400 Bad Request' + bytes(32))}",
     ["the listener there is not a Dask scheduler"]),
    (lambda: f"tcp://127.0.0.1:{_listener(None)}", ["no answer within 1 s"]),
])
def test_a_bad_scheduler_exits_2_quickly_before_any_output(address, words, tmp_path, monkeypatch):
    import time
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("TAA_STUDY_CONNECT_TIMEOUT", "1")
    address = address() if callable(address) else address
    out = tmp_path / "out"
    t0 = time.perf_counter()
    r = CliRunner().invoke(main, ["run", "--scenes", "pipe", "--techniques", "noaa", "--no-agreement",
                                  "--scheduler", address, "--out", str(out)])
    took = time.perf_counter() - t0
    assert r.exit_code == 2, r.output
    assert f"--scheduler {address}: " in r.output, r.output
    for w in words:
        assert w in r.output, (w, r.output)
    assert "Traceback" not in r.output and took < 10, took
    assert not out.exists() and not (tmp_path / "cache").exists()


def test_more_workers_than_cores_are_capped_with_a_note(monkeypatch):
    from study.commands import common
    from study.engine import execute
    monkeypatch.setattr(execute, "cores", lambda: 2)
    notes = []
    monkeypatch.setattr(common.click, "echo", lambda m, err=False: notes.append(m))
    ex = common._executor(64, None, None)
    assert ex.kind == "local" and ex.workers == 2
    assert notes == ["note: --workers 64: this machine has 2 cores; using 2 worker processes"]
    monkeypatch.setenv("TAA_STUDY_WORKERS", "9")
    assert common._executor(None, None, None).workers == 2
    assert "TAA_STUDY_WORKERS 9" in notes[-1]
    assert common._executor(2, None, None).workers == 2 and len(notes) == 2


def test_a_real_dask_scheduler_passes_the_check(monkeypatch):
    """The check's handshake probe accepts a Dask scheduler (a local one, no workers)."""
    from distributed import LocalCluster

    from study.commands.common import _check_scheduler
    monkeypatch.setenv("TAA_STUDY_CONNECT_TIMEOUT", "10")
    with LocalCluster(n_workers=0, processes=False, protocol="tcp://", host="127.0.0.1",
                      dashboard_address=None) as cluster:
        _check_scheduler(cluster.scheduler_address)        # returns (no SystemExit)


def test_a_scene_warning_is_one_plain_line(tmp_path, monkeypatch):
    """A SceneWarning through the CLI: 'warning: <message>', not Python's file:line header and a
    line of this project's source."""
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))

    def degenerate(doc, folder):
        import numpy as np
        data = bytearray((folder / "hand.bin").read_bytes())
        data[148:160] = np.array([2, -1, 0], np.float32).tobytes()   # a zero-area triangle
        (folder / "hand.bin").write_bytes(bytes(data))
    f = _gltf_with(tmp_path, degenerate)
    r = CliRunner().invoke(main, ["estimate", "--scenes", f])
    lines = [ln for ln in r.stderr.splitlines() if "zero-area" in ln]
    assert len(lines) == 1 and lines[0].startswith("warning: ") and "1 zero-area triangles (dropped)" in lines[0], \
        r.stderr
    assert "SceneWarning" not in r.stderr and "warnings.warn" not in r.stderr and ".py:" not in r.stderr, r.stderr


def test_a_technique_file_that_is_not_python_is_named():
    r = CliRunner().invoke(main, ["run", "--scenes", "pipe", "--techniques", "file.txt:Class"])
    assert r.exit_code == 2, r.output
    assert "a technique file must be a Python file" in r.output and "'file.txt'" in r.output, r.output
    assert "is not field=value" not in r.output


def _study(tmp_path, resolution):
    f = tmp_path / "s.toml"
    f.write_text(f'name = "s"\nscenes = ["pipe"]\nresolution = {resolution}\nagreement = false\n'
                 '[[techniques]]\nspec = "noaa"\n')
    return str(f)


def test_sizes_past_the_raster_limit_are_refused_where_they_enter(tmp_path, monkeypatch):
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    r = CliRunner().invoke(main, ["estimate", _study(tmp_path, "[16384, 16384]")])
    assert r.exit_code == 2 and "resolution" in r.output and "8..8192" in r.output and "16384" in r.output, r.output
    scene = tmp_path / "big.toml"
    from study_fixtures import write_scenes
    _, still = write_scenes(tmp_path)
    import re
    scene.write_text(re.sub(r"quick = \[\d+, \d+\]", "quick = [100000, 8]", open(still).read()))
    r = CliRunner().invoke(main, ["estimate", "--scenes", str(scene)])
    assert r.exit_code == 2 and "resolution.quick[0]" in r.output and "8192" in r.output \
        and "100000" in r.output and "Traceback" not in r.output, r.output
    for cmd in (["render", "--scene", "pipe", "--no-reference", "--out", str(tmp_path / "out")],
                ["agree", "--scene", "pipe"], ["bench"]):
        r = CliRunner().invoke(main, cmd + ["--width", "100000", "--height", "16"])
        assert r.exit_code == 2 and "'--width'" in r.output and "100000" in r.output and "8192" in r.output, r.output
    assert not (tmp_path / "out").exists()


def test_a_size_that_does_not_fit_in_memory_is_refused_before_any_output(tmp_path, monkeypatch):
    import raster.limits as L
    monkeypatch.setenv("TAA_STUDY_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(L, "available_memory", lambda: 2 ** 29)          # 0.5 GiB free
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["render", "--scene", "pipe", "--no-reference", "--width", "1024", "--height", "576",
                                  "--out", str(out)])
    assert r.exit_code == 2, r.output
    assert "--scene pipe: 1024x576 needs about 0.7 GiB of memory (256 B/pixel), 0.5 GiB is available" in r.output
    r = CliRunner().invoke(main, ["run", _study(tmp_path, "[1024, 576]"), "--out", str(out)])
    assert r.exit_code == 2 and "scene pipe (study 's', resolution (1024, 576)): 1024x576 needs" in r.output \
        and "0.5 GiB is available" in r.output, r.output
    assert not out.exists() and not (tmp_path / "cache").exists()
    # estimate prints the need of its largest process: here the run task, a render (600 MiB + 256 B a
    # pixel) with No AA's one kept colour frame (12 B a pixel) and its column's share (12)
    monkeypatch.setattr(L, "available_memory", lambda: 2 ** 34)
    r = CliRunner().invoke(main, ["estimate", _study(tmp_path, "[640, 360]"), "--json"])
    mem = json.loads(r.stdout)["memory"]
    assert (mem["width"], mem["height"], mem["scene"], mem["what"]) == (640, 360, "pipe", "a run task")
    assert mem["per_process_gb"] == pytest.approx((600 * 2 ** 20 + (256 + 12 + 12) * 640 * 360) / 2 ** 30)
    assert mem["available_gb"] == 16.0
    r = CliRunner().invoke(main, ["estimate", _study(tmp_path, "[640, 360]")])
    assert "memory: about 0.6 GB per process at its largest (a run task, 640x360, scene pipe)" in r.output

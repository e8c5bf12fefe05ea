"""The GPU path's scripts as far as a machine without one can check them: the offline bundle's plan
(scripts/gpu_bundle.py --dry-run) lists pyproject.toml's own pins for the GPU machine's Python and
platform, nothing fetched; scripts/gpu_check.sh refuses a CUDA variant without a CUDA device."""
import json
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BUNDLE = ROOT / "scripts" / "gpu_bundle.py"


def _plan(*args, code=0):
    r = subprocess.run([sys.executable, str(BUNDLE), "--dry-run", "--no-match-venv", *map(str, args)],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == code, r.stderr
    return json.loads(r.stdout) if code == 0 else r.stderr


def test_the_bundle_plan_is_pyprojects_pins_for_the_gpu_machine(tmp_path):
    p = _plan("--out", tmp_path / "b")
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    deps = project["dependencies"]
    tests = [r for r in project["optional-dependencies"]["test"] if r.startswith("pytest") and "xdist" not in r]
    assert p["requirements"] == deps + tests                   # each pin exactly as pyproject.toml writes it
    for pin in ("mitsuba==3.9.1", "drjit==1.5.0", "torch==2.9.1", "cvvdp==0.5.7"):
        assert pin in deps and pin in p["requirements"]
    assert not any(re.match(r"(selenium|pdfminer|pytest-xdist)", r) for r in p["requirements"])
    download = next(s["cmd"] for s in p["steps"] if s["step"] == "download")
    assert "--only-binary=:all:" in download and "--no-deps" in download
    assert download[download.index("--python-version") + 1] == "3.12" and "cp312" in download
    assert "manylinux_2_28_x86_64" in download
    resolve = next(s["cmd"] for s in p["steps"] if s["step"] == "resolve")
    assert resolve[resolve.index("--python-platform") + 1] == "x86_64-manylinux_2_28"
    assert not (tmp_path / "b").exists()                          # a dry run writes nothing


def test_the_bundle_without_video_and_for_another_python(tmp_path):
    p = _plan("--no-video", "--python", "3.11", "--out", tmp_path / "b")
    assert not any(re.match(r"(torch|torchvision|cvvdp)\b", r) for r in p["requirements"])
    assert "mitsuba==3.9.1" in p["requirements"] and "cp311" in p["steps"][2]["cmd"]
    assert p["steps"][-1]["cmd"][2].endswith("gpu-bundle-3.11.tar")


def test_the_bundle_reads_the_pins_it_is_given_and_refuses_bad_input(tmp_path):
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "x"\ndependencies = ["mitsuba==9.9.9", '
                                             '"torch==1.0"]\n[project.optional-dependencies]\n'
                                             'test = ["pytest==8.0", "selenium==1"]\n')
    p = _plan("--pyproject", tmp_path / "pyproject.toml", "--out", tmp_path / "b")
    assert p["requirements"] == ["mitsuba==9.9.9", "torch==1.0", "pytest==8.0"]
    assert "--python '3'" in _plan("--python", "3", code=2)
    assert "cannot read its [project]" in _plan("--pyproject", tmp_path / "none.toml", code=2)


def test_gpu_check_refuses_a_cuda_variant_without_a_cuda_device(tmp_path):
    """An nvidia-smi that finds no device (as on a machine whose driver sees none) stands first on the
    PATH, so the check is the same on any machine."""
    bin_ = tmp_path / "bin"
    bin_.mkdir()
    (bin_ / "nvidia-smi").write_text("#!/bin/sh\necho 'No devices were found'\nexit 6\n")
    (bin_ / "nvidia-smi").chmod(0o755)
    env = {**os.environ, "OUT": str(tmp_path / "out"), "PATH": f"{bin_}:/usr/bin:/bin", "TAA_VARIANT": "cuda_ad_rgb"}
    r = subprocess.run(["bash", str(ROOT / "scripts" / "gpu_check.sh")], capture_output=True, text=True,
                       env=env, timeout=60)
    assert r.returncode == 2, r.stdout + r.stderr
    said = r.stdout + r.stderr          # the script tees both into $OUT/gpu_check.log
    assert "gpu_check: no CUDA device (nvidia-smi lists no GPU) for TAA_VARIANT=cuda_ad_rgb" in said
    assert "unpacking" not in said and "installing" not in said          # refused before anything
    assert "no CUDA device" in (tmp_path / "out" / "gpu_check.log").read_text()

"""Complete cache keys (issue 11): in a temporary copy of the project, editing any source file a
task depends on changes that task's key, and each task's code closure holds the files it must."""
import json
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("backend", "provenance", "display", "scenes", "shading", "raster", "references", "taa_impl", "study")

# The code each task kind's key names (study.plan.CODE); the test checks the files its closure holds.
PROBE = r'''
import json, os, sys
import backend, provenance, taa_impl
from study.plan import CODE
KINDS = {
    "run baseline": [taa_impl.BaselineTAA, *CODE["run"]],
    "run fxaa": [taa_impl.FXAA, *CODE["run"]],
    "run smaa": [taa_impl.SMAA, *CODE["run"]],
    "run improved": [taa_impl.ImprovedTAA, *CODE["run"]],
    "metrics": list(CODE["metrics"]),
    "reference": list(CODE["reference"]),
    "agreement": list(CODE["agreement"]),
}
root = os.getcwd()
report = {}
for kind, code in KINDS.items():
    files = provenance.closure_files(*code)
    before = provenance.code_token(*code)
    unchanged = []
    for f in files:
        text = f.read_bytes()
        f.write_bytes(text + b"\n# edited\n")
        st = os.stat(f)
        os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
        if provenance.code_token(*code) == before:
            unchanged.append(str(f))
        f.write_bytes(text)
        os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns + 2 * 10**9))
    report[kind] = {"files": [os.path.relpath(f, root) for f in files], "unchanged": unchanged,
                    "restored": provenance.code_token(*code) == before}
print(json.dumps(report))
'''


def test_editing_any_dependency_changes_the_key(tmp_path):
    for pkg in PACKAGES:
        shutil.copytree(ROOT / pkg, tmp_path / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    r = subprocess.run([sys.executable, "-c", PROBE], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout.splitlines()[-1])
    for kind, rep in report.items():
        assert rep["files"] and rep["unchanged"] == [], (kind, rep["unchanged"])
        assert rep["restored"], kind
    run_files = set(report["run baseline"]["files"])
    for f in ("raster/frames.py", "raster/visibility.py", "raster/shaders/vis.frag", "shading/surface.py",
              "scenes/camera.py", "scenes/jitter.py", "study/protocols.py", "taa_impl/baseline.py",
              "taa_impl/kernels.py"):
        assert f in run_files, f
    for kind in ("run fxaa", "run smaa", "metrics", "reference"):
        assert "display/__init__.py" in report[kind]["files"], kind       # the display transform
    assert "taa_impl/smaa_area.py" in report["run smaa"]["files"]
    assert "taa_impl/improved.py" in report["run improved"]["files"]
    assert "taa_impl/improved.py" not in run_files                          # an edit elsewhere: no recompute
    assert "references/render.py" in report["reference"]["files"]
    assert "study/metrics.py" in report["metrics"]["files"]
    assert "references/render.py" in report["agreement"]["files"]

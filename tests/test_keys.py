"""Complete cache keys: in a temporary copy of the project, editing any source file a
task depends on changes that task's key, and each task's code closure holds the files it must."""
import json
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("backend", "provenance", "display", "scenes", "shading", "raster", "references", "taa_impl", "study")

# The code each task kind's key names (study.engine.plan.CODE); the test checks the files its closure holds.
PROBE = r'''
import json, os, sys
import backend, provenance, taa_impl
from study.engine.plan import CODE
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


def probe_in_copy(tmp_path, probe: str):
    """Run `probe` in a temporary copy of the project's packages; its last line of output as JSON."""
    for pkg in PACKAGES:
        shutil.copytree(ROOT / pkg, tmp_path / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    r = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.splitlines()[-1])


def test_editing_any_dependency_changes_the_key(tmp_path):
    report = probe_in_copy(tmp_path, PROBE)
    for kind, rep in report.items():
        assert rep["files"] and rep["unchanged"] == [], (kind, rep["unchanged"])
        assert rep["restored"], kind
    run_files = set(report["run baseline"]["files"])
    for f in ("raster/frames.py", "raster/visibility.py", "raster/shaders/vis.frag", "shading/surface.py",
              "scenes/camera.py", "scenes/jitter.py", "study/config/protocols.py", "study/engine/drive.py",
              "study/engine/run_task.py", "taa_impl/baseline.py",
              "taa_impl/kernels.py"):
        assert f in run_files, f
    for kind in ("run fxaa", "run smaa", "metrics", "reference"):
        assert "display/__init__.py" in report[kind]["files"], kind       # the display transform
    assert "taa_impl/smaa_area.py" in report["run smaa"]["files"]
    assert "taa_impl/improved.py" in report["run improved"]["files"]
    assert "taa_impl/improved.py" not in run_files                          # an edit elsewhere: no recompute
    assert "references/render.py" in report["reference"]["files"]
    for f in ("study/metrics/suite.py", "study/metrics/ssim.py", "study/metrics/flip.py", "study/metrics/filters.py",
              "study/metrics/judging.py", "study/metrics/temporal.py", "study/metrics/ssim_window.py",
              "study/metrics/ssim_passes.py", "study/metrics/ssim_against.py", "study/metrics/flip_colour.py",
              "study/metrics/flip_passes.py",
              "study/engine/judge.py"):
        assert f in report["metrics"]["files"], f
    assert "references/render.py" in report["agreement"]["files"]


# Which task kinds re-key when one module of the study is edited: the run key names only the code a
# run uses (its driver, its task, the protocols, the technique), the metrics key only the metric code,
# and the engine's bookkeeping, the defaults (their values reach keys as data), the reporting and
# the commands re-key nothing.
REKEY_PROBE = r'''
import json, os, sys
from pathlib import Path
import provenance, taa_impl
from study.engine.plan import CODE
for m in sorted(Path("study").rglob("*.py")):          # every module loaded, as in a study process
    name = ".".join(m.with_suffix("").parts).removesuffix(".__init__")
    if name != "study.__main__":
        __import__(name)
KINDS = {"run": [taa_impl.BaselineTAA, *CODE["run"]], "metrics": list(CODE["metrics"]),
         "reference": list(CODE["reference"]), "agreement": list(CODE["agreement"]),
         "cost": [taa_impl.BaselineTAA, "study.engine.costs"]}
out = {}
for f in sorted(Path("study").rglob("*")):
    if not f.is_file() or "__pycache__" in f.parts:
        continue
    before = {k: provenance.code_token(*c) for k, c in KINDS.items()}
    text = f.read_bytes()
    st = os.stat(f)
    f.write_bytes(text + b"\n# edited\n")
    os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    out[str(f)] = sorted(k for k, c in KINDS.items() if provenance.code_token(*c) != before[k])
    f.write_bytes(text)
    os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns + 2 * 10**9))
print(json.dumps(out))
'''

REKEYS = {
    "study/metrics/suite.py": {"metrics"},
    "study/metrics/ssim.py": {"metrics"},
    "study/metrics/flip.py": {"metrics"},
    "study/metrics/flip_colour.py": {"metrics"},
    "study/metrics/flip_passes.py": {"metrics"},
    "study/metrics/ssim_window.py": {"metrics"},
    "study/metrics/ssim_passes.py": {"metrics"},
    "study/metrics/ssim_against.py": {"metrics"},
    "study/metrics/judging.py": {"metrics"},
    "study/metrics/temporal.py": {"metrics"},
    "study/metrics/filters.py": {"metrics"},
    "study/metrics/checks.py": {"metrics"},         # what the metrics refuse is part of what they judge
    "study/metrics/uncertainty.py": {"metrics", "agreement"},   # both remove the reference's bias with it
    "study/engine/judge.py": {"metrics"},
    "study/engine/drive.py": {"run", "cost"},         # costs time the driver's steps
    "study/engine/run_task.py": {"run"},
    "study/config/protocols.py": {"run", "cost"},    # the schedules' steps and the raster frames they need
    "study/config/lod.py": {"run", "cost"},          # the texture LOD bias of a column's raster frames
    "study/engine/tasks.py": {"run", "metrics", "agreement"},   # the task contract: errors, setup
    "study/engine/agreement.py": {"agreement"},
    "study/engine/costs.py": {"cost"},
}


def test_each_study_module_rekeys_only_what_it_makes(tmp_path):
    got = probe_in_copy(tmp_path, REKEY_PROBE)
    assert len(got) > 40, sorted(got)
    wrong = {}
    for f, kinds in got.items():
        want = next((v for k, v in REKEYS.items() if f == k or (k.endswith("/") and f.startswith(k))), set())
        if set(kinds) != want:
            wrong[f] = (kinds, sorted(want))
    assert not wrong, wrong      # file -> (kinds it re-keys, kinds it should)


def test_a_code_key_does_not_depend_on_which_submodules_the_process_loaded(tmp_path, monkeypatch):
    """Importing a.b anywhere binds b on package a. The closure took every loaded submodule of a
    package it used, so a process that had loaded one more (a test, another command) computed other
    keys than the study that cached the tasks, and made them again. Its `import a.b.c` statements
    still count: they load a.b.c without binding it."""
    import importlib
    import os

    import provenance
    pkg = tmp_path / "keypkg"
    (pkg / "deep").mkdir(parents=True)
    (pkg / "__init__.py").write_text("from .core import f\n")
    (pkg / "core.py").write_text("def f():\n    return 1\n")
    (pkg / "sibling.py").write_text("X = 2\n")
    (pkg / "deep" / "__init__.py").write_text("")
    (pkg / "deep" / "leaf.py").write_text("V = 3\n")
    (tmp_path / "keyuser.py").write_text("import keypkg\nimport keypkg.deep.leaf\n\n\n"
                                         "def g():\n    return keypkg.f() + keypkg.deep.leaf.V\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        keyuser = importlib.import_module("keyuser")

        def files():
            return sorted(p.relative_to(tmp_path).as_posix() for p in provenance.closure_files(keyuser))
        first, token = files(), provenance.code_token(keyuser)
        assert first == ["keypkg/__init__.py", "keypkg/core.py", "keypkg/deep/__init__.py",
                         "keypkg/deep/leaf.py", "keyuser.py"]
        importlib.import_module("keypkg.sibling")           # another part of the process loads it
        provenance._closure.cache_clear()
        assert files() == first and provenance.code_token(keyuser) == token
        leaf = pkg / "deep" / "leaf.py"
        leaf.write_text("V = 4\n")
        st = os.stat(leaf)
        os.utime(leaf, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
        assert provenance.code_token(keyuser) != token      # reached through `import keypkg.deep.leaf` alone
    finally:
        provenance._closure.cache_clear()
        for name in [m for m in sys.modules if m == "keyuser" or m.split(".")[0] == "keypkg"]:
            del sys.modules[name]

def test_a_normalized_value_keys_exactly_as_the_value_itself():
    """The planner keys a test's runs by its schedule normalised once: every key must be the one the
    plain schedule gives (a changed key would re-make every cached run), and a different schedule
    still a different key."""
    import numpy as np

    from provenance import Normalized, task_key
    steps = [(t, t % 3, t % 2 == 0, t == 0, t - 1 if t else None, t) for t in range(40)]
    data = {"scene": "abc", "res": (32, 18), "schedule": steps, "technique": {"p": np.float32(0.5), "n": [1, 2]}}
    pre = dict(data, schedule=Normalized(steps))
    assert task_key("run", pre, ["ref-1"]) == task_key("run", data, ["ref-1"])
    assert task_key("run", [pre, pre]) == task_key("run", [data, data])
    frames = {f: f // 2 for f in range(0, 256, 3)}            # a test's judged frames: frame -> scene time
    assert task_key("metrics", {"frames": Normalized(frames), "maps": [1]}, ["run-1"]) == \
        task_key("metrics", {"frames": frames, "maps": [1]}, ["run-1"])
    other = dict(data, schedule=Normalized(steps[:-1]))
    assert task_key("run", other, ["ref-1"]) != task_key("run", data, ["ref-1"])

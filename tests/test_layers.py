"""The dependency rule: every import points down the data flow, never up or sideways.

  backend, provenance, display  ->  scenes  ->  shading  ->  raster | references  ->  taa_impl
  ->  study.metrics | study.config  ->  study.engine  ->  study.reporting  ->  study.commands

A module may import its own unit and units of lower layers only ('|' separates units of one layer,
which may not import each other). The reporting reads the engine's results alone
(study.engine.results), never its store, plan or tasks. Every import counts, function-local ones too.
"""
import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

LAYERS = [
    ("backend", "provenance", "display"),
    ("scenes",),
    ("shading",),
    ("raster", "references"),
    ("taa_impl",),
    ("study.metrics", "study.config"),
    ("study.engine",),
    ("study.reporting",),
    ("study.commands",),
    ("study",),                     # the package itself and its __main__
]
LAYER = {unit: i for i, units in enumerate(LAYERS) for unit in units}
# The engine modules the reporting may read.
REPORTING_READS = {"study.engine.results"}


def unit_of(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] == "study" and len(parts) > 1 and f"study.{parts[1]}" in LAYER:
        return f"study.{parts[1]}"
    return parts[0] if parts[0] in LAYER else None


def module_name(path: Path) -> str:
    return ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")


def imports(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module) of every import in the file."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module
            # `from pkg import sub` imports the submodule sub
            out += [(node.lineno, f"{mod}.{a.name}") for a in node.names]
    return out


def violations() -> list[str]:
    bad = []
    files = [p for u in LAYER if "." not in u for p in (ROOT / u).rglob("*.py")]
    for path in sorted(set(files)):
        src = module_name(path)
        su = unit_of(src)
        for line, mod in imports(path):
            du = unit_of(mod)
            if du is None or du == su:
                continue
            where = f"{path.relative_to(ROOT)}:{line} imports {mod}"
            if LAYER[du] >= LAYER[su]:
                bad.append(f"{where} ({du} is not below {su})")
            elif su == "study.reporting" and du == "study.engine" and \
                    not any(mod == r or mod.startswith(r + ".") for r in REPORTING_READS):
                bad.append(f"{where} (the reporting reads only {sorted(REPORTING_READS)})")
    return bad


def test_every_import_points_down():
    assert violations() == []


def test_the_rule_catches_an_upward_and_a_sideways_import(tmp_path, monkeypatch):
    # the checker itself: an engine module importing the reporting, the reporting reading the store,
    # and raster importing references are each reported
    fake = tmp_path / "proj"
    for rel, text in {"study/__init__.py": "", "study/engine/__init__.py": "",
                      "study/engine/plan.py": "from study.reporting import report\n",
                      "study/reporting/__init__.py": "",
                      "study/reporting/report.py": "def f():\n    from study.engine.store import Store\n",
                      "raster/__init__.py": "from references import cache\n",
                      "references/__init__.py": "from . import cache\n", "references/cache.py": ""}.items():
        (fake / rel).parent.mkdir(parents=True, exist_ok=True)
        (fake / rel).write_text(text)
    monkeypatch.setattr(__import__(__name__), "ROOT", fake)
    got = violations()
    assert any("study/engine/plan.py:1 imports study.reporting.report" in v for v in got), got
    assert any("study/reporting/report.py:2 imports study.engine.store" in v for v in got), got
    assert any("raster/__init__.py:1 imports references.cache" in v for v in got), got
    assert len(got) == 3, got


def test_no_module_is_over_400_lines():
    long = {str(p.relative_to(ROOT)): n for u in LAYER if "." not in u for p in (ROOT / u).rglob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > 400}
    assert set(long) <= {"taa_impl/smaa.py"}, long     # 409 lines: SMAA's three passes, one unit

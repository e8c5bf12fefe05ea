"""An installed (not editable) copy holds every module and data file: a cluster worker gets one."""
import fnmatch
import tomllib
from pathlib import Path

from setuptools import find_packages

ROOT = Path(__file__).resolve().parent.parent
CFG = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


def test_every_package_and_data_file_is_installed():
    tops = [p.parent for p in ROOT.glob("*/__init__.py") if p.parent.name != "tests"]
    own = {str(p.parent.relative_to(ROOT)).replace("/", ".") for top in tops for p in top.glob("**/__init__.py")}
    found = set(find_packages(str(ROOT), include=CFG["packages"]["find"]["include"]))
    assert own <= found, sorted(own - found)
    data = CFG["package-data"]
    for pkg in sorted(found):
        folder = ROOT / pkg.replace(".", "/")
        for f in folder.rglob("*"):
            if f.is_file() and f.suffix not in (".py", ".pyc") and "__pycache__" not in f.parts:
                rel = str(f.relative_to(folder))
                # data files of a subpackage belong to that subpackage's own entry
                if any((folder / part).joinpath("__init__.py").exists() for part in f.relative_to(folder).parts[:-1]):
                    continue
                assert any(fnmatch.fnmatch(rel, pat) for pat in data.get(pkg, [])), f"{pkg}: {rel} not in package-data"

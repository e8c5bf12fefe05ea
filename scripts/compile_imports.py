"""Writes the bytecode of what a study and the suite import, once, at set-up.

uv installs packages without compiling them (pip would), so every new process (each test worker,
each Dask worker, each command the suite starts) compiled torch's, Mitsuba's and Dask's Python
again until one of them had written the .pyc files: about 17 s of CPU for each process that got
there first. Compiling all of site-packages costs three times that (55 s), most of it for modules
nothing here imports; importing every module of the project, and the packages it imports only
inside functions, writes exactly the files that are read.
"""
from __future__ import annotations

import importlib
import pkgutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("backend", "provenance", "display", "scenes", "shading", "raster", "references", "taa_impl", "study")
# imported inside functions (optional or heavy): the video metric, clusters, plots, the PDF and
# HTML tests, FLIP
LAZY = ("torch", "pycvvdp", "distributed", "dask.distributed", "matplotlib.pyplot", "pdfminer.high_level",
        "flip_evaluator", "psutil", "jinja2", "selenium.webdriver", "skimage.metrics", "scipy.ndimage",
        "pytest", "xdist")


def main() -> int:
    sys.path.insert(0, str(ROOT))
    names = list(PACKAGES)
    for pkg in PACKAGES:
        mod = importlib.import_module(pkg)
        if hasattr(mod, "__path__"):
            names += [m.name for m in pkgutil.walk_packages(mod.__path__, pkg + ".") if not m.name.endswith("__main__")]
    failed = []
    for name in [*names, *LAZY]:
        try:
            importlib.import_module(name)
        except Exception as exc:        # noqa: BLE001  (a module that cannot load here is named, not fatal)
            failed.append(f"{name} ({type(exc).__name__}: {exc})")
    print(f"setup: bytecode of {len(sys.modules)} modules written"
          + (f"; not importable here: {', '.join(failed)}" if failed else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())

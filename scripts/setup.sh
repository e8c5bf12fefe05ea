#!/usr/bin/env bash
# Installs everything the project needs on a fresh Debian machine: the system libraries (a libLLVM
# that Dr.Jit accepts, Mesa's EGL for headless OpenGL, Chromium and its WebDriver for the HTML
# report's browser test) and a virtual environment in .venv. LaTeX is installed by `make paper`
# and `make test` (scripts/setup_latex.sh), not here: `make study` does not need it.
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/apt_install.sh setup libllvm19 libegl1 libegl-mesa0 libgl1-mesa-dri libglx-mesa0 \
    chromium chromium-driver

PYTHON="${PYTHON:-python3}"
if ! "$PYTHON" -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
    echo "setup: Python >= 3.11 is needed (found $("$PYTHON" --version 2>&1))" >&2
    exit 1
fi
if [ ! -x .venv/bin/python ]; then
    echo "setup: creating .venv"
    "$PYTHON" -m venv .venv
fi
# uv installs the pinned packages: torch and its CUDA libraries (for cvvdp) are ~4 GB of wheels,
# which pip unpacks in ~3.5 min here and uv in ~45 s.
.venv/bin/python -m pip install -q uv==0.13.9
echo "setup: installing Python packages (pinned in pyproject.toml)"
.venv/bin/uv pip install -q --python .venv/bin/python -e '.[test]'
# Fails here, with an instruction, if no usable libLLVM or EGL driver was found.
.venv/bin/python -c "import backend; print('setup: Dr.Jit', backend.dr.__version__, 'variant', backend.VARIANT)"
# uv writes no bytecode: what the study and the suite import is compiled here, once, instead of in
# each new process (scripts/compile_imports.py says why not all of site-packages).
PYTHONDONTWRITEBYTECODE= .venv/bin/python scripts/compile_imports.py

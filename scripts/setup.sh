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
.venv/bin/python -m pip install -q --upgrade pip
echo "setup: installing Python packages (pinned in pyproject.toml)"
.venv/bin/python -m pip install -q -e '.[test]'
# Fails here, with an instruction, if no usable libLLVM or EGL driver was found.
.venv/bin/python -c "import backend; print('setup: Dr.Jit', backend.dr.__version__, 'variant', backend.VARIANT)"

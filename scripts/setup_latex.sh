#!/usr/bin/env bash
# The LaTeX toolchain `make paper` needs (Debian packages), installed only when missing; `make test`
# and `make study` never call this. pdfinfo/pdftoppm (poppler-utils) let the PDF be checked and looked at.
set -euo pipefail

bash "$(dirname "$0")/apt_install.sh" setup_latex latexmk texlive-latex-recommended texlive-latex-extra \
    texlive-fonts-recommended lmodern poppler-utils
command -v latexmk >/dev/null && command -v pdflatex >/dev/null || {
    echo "setup_latex: latexmk or pdflatex still missing after the install" >&2; exit 1; }

#!/usr/bin/env bash
# The LaTeX toolchain the paper needs (Debian packages), installed only when missing: `make paper`
# and `make test` (whose PDF tests build the paper) call this, `make study` does not. The smallest
# set that builds paper/main.tex: no texlive-latex-extra (80 MB, with Java and TeX's picture
# packages) since tables are shrunk with graphicx, not adjustbox. pdfinfo/pdftoppm (poppler-utils)
# let the PDF be checked and looked at.
set -euo pipefail

bash "$(dirname "$0")/apt_install.sh" setup_latex latexmk texlive-latex-recommended lmodern poppler-utils
command -v latexmk >/dev/null && command -v pdflatex >/dev/null || {
    echo "setup_latex: latexmk or pdflatex still missing after the install" >&2; exit 1; }

#!/usr/bin/env bash
# The LaTeX toolchain `make paper` needs (Debian packages), installed only when missing; `make test`
# and `make study` never call this. pdfinfo/pdftoppm (poppler-utils) let the PDF be checked and looked at.
set -euo pipefail

APT_PACKAGES=(latexmk texlive-latex-recommended texlive-latex-extra texlive-fonts-recommended lmodern poppler-utils)
missing=()
for pkg in "${APT_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if ((${#missing[@]})); then
    echo "setup_latex: installing Debian packages: ${missing[*]}"
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    start=$(date +%s)
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
    echo "setup_latex: installed in $(( $(date +%s) - start )) s"
fi
command -v latexmk >/dev/null && command -v pdflatex >/dev/null || {
    echo "setup_latex: latexmk or pdflatex still missing after the install" >&2; exit 1; }

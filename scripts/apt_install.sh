#!/usr/bin/env bash
# Installs the Debian packages given that are not installed yet (apt-get update first), and
# nothing else. Usage: apt_install.sh TAG PACKAGE... (TAG prefixes the messages).
set -euo pipefail
tag=$1; shift
missing=()
for pkg in "$@"; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
((${#missing[@]})) || exit 0
echo "$tag: installing Debian packages: ${missing[*]}"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
start=$(date +%s)
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "$tag: installed in $(( $(date +%s) - start )) s"

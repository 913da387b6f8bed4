#!/usr/bin/env bash
# One-time set-up on a fresh machine: the Debian packages the desktop app needs (an X
# server for the 3D views), and a virtual environment in .venv with the CPU build of
# PyTorch and the workbench installed (editable, with the test tools).
set -euo pipefail
cd "$(dirname "$0")"

DEBIAN_PACKAGES=(xvfb xauth libxcb-icccm4 libxcb-keysyms1)
if command -v apt-get >/dev/null 2>&1; then
  missing=()
  for pkg in "${DEBIAN_PACKAGES[@]}"; do
    dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
  fi
fi

[ -x .venv/bin/python ] || python3 -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
# The CPU build first: an unpinned torch would pull a CUDA build of several GB.
.venv/bin/python -m pip install -q torch==2.13.0
.venv/bin/python -m pip install -q -e ".[test]"
echo "set-up done: run .venv/bin/workbench --help"

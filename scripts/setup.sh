#!/usr/bin/env bash
# Installs everything the project needs on a Debian machine with python3 and gcc:
# valgrind (Debian package, for the leak test), chromium (Debian package, the headless browser the
# test of twin watch's live page loads it in), Python's headers (python3-dev, when missing), a
# virtual environment in .venv with the package,
# its test tools and Dask. Idempotent; safe to run again.
set -euo pipefail
cd "$(dirname "$0")/.."

as_root() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }
apt_install() {
  as_root apt-get update -qq
  DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -qq "$@" >/dev/null
}

command -v valgrind >/dev/null || apt_install valgrind
command -v chromium >/dev/null || apt_install chromium
# Python's headers: `twin build` compiles the loops ahead with them (numba.pycc)
python3 -c 'import os, sysconfig; raise SystemExit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))' \
  || apt_install python3-dev
if [ ! -x .venv/bin/python ]; then
  python3 -m venv .venv 2>/dev/null || { apt_install python3-venv && python3 -m venv .venv; }
fi
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -e ".[test,dask]"

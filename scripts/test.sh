#!/usr/bin/env bash
# Sets up (scripts/setup.sh), checks lint and format, builds the FMU and runs the whole test suite
# in two processes (pytest-xdist; `-n 0` after the command runs it in one).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check .
.venv/bin/ruff format --check .
.venv/bin/python -m pytest -q -n 2 "$@"

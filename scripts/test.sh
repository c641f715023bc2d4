#!/usr/bin/env bash
# Sets up (scripts/setup.sh), checks lint and format, builds the FMU and runs the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check .
.venv/bin/ruff format --check .
.venv/bin/python -m pytest -q "$@"

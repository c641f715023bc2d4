#!/usr/bin/env bash
# The main job on the default scenario: set up, build the plant FMU, simulate reference 1 with the
# Fine-Tune set, check the paper's Table 3 sets on references 1 and 2. Results go to out/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
twin() { .venv/bin/python -m twin_cosim "$@"; }
twin build
twin simulate scenarios/reference1.yaml --out out/reference1
twin table3 scenarios/reference1.yaml scenarios/reference2.yaml --out out/table3

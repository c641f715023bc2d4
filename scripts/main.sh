#!/usr/bin/env bash
# The main job on the default scenario: set up, build the plant FMU, simulate reference 1 with the
# Fine-Tune set, run a CE campaign with the paper's settings on reference 1 and write the paper's
# Tables 3-5 for it (reference 2 for validation) with their plots, and check the paper's Table 3
# sets. Results go to out/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
twin() { .venv/bin/python -m twin_cosim "$@"; }
twin build
twin simulate scenarios/reference1.yaml --out out/reference1
twin compare scenarios/paper_campaign.yaml --methods ce --out out/main-ce --quiet
twin table3 scenarios/reference1.yaml scenarios/reference2.yaml --out out/table3

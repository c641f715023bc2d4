#!/usr/bin/env bash
# The package as a user installs it: build the wheel, install it into a fresh virtual environment
# in a temporary folder, and run the README's install commands from an empty folder there
# (build the FMU from the C sources in the wheel into a fresh cache, simulate the shipped
# reference 1 by name, a short CE campaign). Everything is removed at the end.
set -euo pipefail
cd "$(dirname "$0")/.."
python=python3
[ -x .venv/bin/python ] && python=.venv/bin/python
tmp="$(mktemp -d -t twin-wheel-XXXXXX)"
trap 'rm -rf "$tmp"' EXIT
"$python" -m pip wheel -q --no-deps -w "$tmp/dist" .
python3 -m venv "$tmp/venv"
"$tmp/venv/bin/python" -m pip install -q "$tmp"/dist/twin_cosim-*.whl
mkdir "$tmp/work"
cd "$tmp/work"
export TWIN_COSIM_CACHE="$tmp/cache"
twin="$tmp/venv/bin/twin"
set -x
"$twin" --help >/dev/null
"$twin" build
"$twin" simulate reference1
"$twin" optimize reference1 --method ce --budget 40 --workers 2 --quiet --out campaign
set +x
test -s out/reference1/summary.json
test -s campaign/result.json
echo "wheel: installed and ran from an empty folder"

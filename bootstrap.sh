#!/usr/bin/env bash
# Create .venv beside this file and install the package with its runtime and test dependencies.
# Idempotent: a second run only re-checks the install. Needs python3 (3.11+) with venv.
set -euo pipefail
cd "$(dirname "$0")"
PYTHON=${PYTHON:-python3}
if [[ ! -x .venv/bin/python ]]; then
  "$PYTHON" -m venv .venv
fi
stamp=.venv/.dual_arm_control-installed
if [[ ! -f $stamp || requirements.txt -nt $stamp || setup.py -nt $stamp ]]; then
  .venv/bin/python -m pip install -q -U pip
  .venv/bin/python -m pip install -q -r requirements.txt
  .venv/bin/python -m pip install -q --no-deps -e .
  touch "$stamp"
fi
# Foxglove's decoders for the bag tests (test/foxglove), pinned by its lock file; reinstalled only
# when the lock file changed since the last install.
foxglove=test/foxglove
if ! command -v npm >/dev/null; then
  echo 'bootstrap.sh: npm not found: test/test_bags.py needs Node.js and npm (test/foxglove)' >&2
elif ! cmp -s "$foxglove/package-lock.json" "$foxglove/node_modules/.installed-lock.json"; then
  (cd "$foxglove" && npm ci --ignore-scripts --no-audit --no-fund --loglevel=error)
  cp "$foxglove/package-lock.json" "$foxglove/node_modules/.installed-lock.json"
fi

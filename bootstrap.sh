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

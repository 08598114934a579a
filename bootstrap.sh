#!/usr/bin/env bash
# Create .venv beside this file and install the package with its runtime and test dependencies.
# Also builds tf2_msgs from its message definition (tools/build_tf2_msgs.py; needs gcc, g++).
# Idempotent: a second run only re-checks the install. Needs python3 (3.11+) with venv.
set -euo pipefail
cd "$(dirname "$0")"
PYTHON=${PYTHON:-python3}
if [[ ! -x .venv/bin/python ]]; then
  "$PYTHON" -m venv .venv
fi
stamp=.venv/.dual_arm_control-installed
if [[ ! -f $stamp || requirements.txt -nt $stamp || setup.py -nt $stamp
      || dual_arm_control/executables.py -nt $stamp ]]; then
  .venv/bin/python -m pip install -q -U pip
  .venv/bin/python -m pip install -q -r requirements.txt
  .venv/bin/python -m pip install -q --no-deps -e .
  touch "$stamp"
fi
# tf2_msgs (for /tf and /tf_static) has no pip wheel: generate and compile it with the rosidl
# generators the ROS wheels bring (gcc and g++ needed), into .venv. Log: .venv/build/tf2_msgs.log
tf_stamp=.venv/.tf2_msgs-built
if [[ ! -f $tf_stamp || tools/build_tf2_msgs.py -nt $tf_stamp || interfaces/tf2_msgs -nt $tf_stamp
      || interfaces/tf2_msgs/msg/TFMessage.msg -nt $tf_stamp || $stamp -nt $tf_stamp ]]; then
  mkdir -p .venv/build
  if ! AMENT_PREFIX_PATH="$PWD/.venv" .venv/bin/python tools/build_tf2_msgs.py \
      > .venv/build/tf2_msgs.log 2>&1; then
    tail -n 20 .venv/build/tf2_msgs.log >&2
    echo "bootstrap: building tf2_msgs failed (full log: .venv/build/tf2_msgs.log)" >&2
    exit 1
  fi
  touch "$tf_stamp"
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

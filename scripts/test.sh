#!/usr/bin/env bash
# The README's test command: install everything (idempotent), then run the whole pytest suite
# loopback-only. Extra arguments go to pytest (e.g. `bash scripts/test.sh -k planner`).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
bash "$ROOT/scripts/bootstrap.sh"
cd "$ROOT"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export AMENT_PREFIX_PATH="$ROOT/.venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
export PYTHONUNBUFFERED=1 MPLBACKEND=Agg
set +e
"$ROOT/.venv/bin/python" -m pytest -q -p no:cacheprovider "$@" test
rc=$?
set -e
if [ $rc -eq 5 ]; then echo "pytest collected no tests: that is a failure (issue 19)" >&2; exit 1; fi
exit $rc

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
PY="$ROOT/.venv/bin/python"
# Two pytest-xdist workers (SKILLGEN_TEST_WORKERS; 0 runs one process), whole files to a worker
# (--dist loadfile: a module's graph fixture starts once). Much of the suite waits on nodes, DDS discovery
# and subprocess start-up, so two workers on two cores took 21.7 min where one process took 28.2, the same
# run under the same load, and 14.4 min on the quiet machine (one process: 23.0; 2026-12-06, docs/testing.md). ROS domains are flock-leased across processes, and
# test/conftest.py fails a module without tests in either mode. (test_hsp_graph.py once ran in its own
# process: a reliable reader on the lockstep loop held samples back for 10 s in long processes; fixed by
# best-effort readers; docs/hsp.md "Known problems".)
WORKERS=${SKILLGEN_TEST_WORKERS:-2}
set +e
"$PY" -m pytest -q -p no:cacheprovider --durations=25 -n "$WORKERS" --dist loadfile "$@" test
rc=$?
set -e
if [ $rc -eq 5 ]; then echo "pytest collected no tests: that is a failure (issue 19)" >&2; exit 1; fi
exit $rc

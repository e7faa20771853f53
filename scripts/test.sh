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
# test_hsp_graph.py runs in a pytest process of its own: after the rest of the suite in the same
# process its deploy graph's driver took no osc_target for 10 s+ after an executed trajectory (never
# when the module ran alone). Fixed by best-effort readers on the lockstep loop (docs/hsp.md "Known
# problems"); this stays until more single-process runs have confirmed it.
ISOLATED=test/test_hsp_graph.py
PY="$ROOT/.venv/bin/python"
selects() {  # the arguments select a test there, or collecting fails (the real run then shows why)
  local out st
  out=$("$PY" -m pytest --co -q -p no:cacheprovider "$@" 2>&1); st=$?
  [ $st -eq 0 ] || grep -qi "error" <<<"$out"
}
set +e
rc=5; rc2=5  # 5: the arguments (-k ...) select no test there
if selects "$@" --ignore="$ISOLATED" test; then "$PY" -m pytest -q -p no:cacheprovider "$@" --ignore="$ISOLATED" test; rc=$?; fi
if selects "$@" "$ISOLATED"; then "$PY" -m pytest -q -p no:cacheprovider "$@" "$ISOLATED"; rc2=$?; fi
set -e
if [ $rc -eq 5 ] && [ $rc2 -eq 5 ]; then echo "pytest collected no tests: that is a failure (issue 19)" >&2; exit 1; fi
[ $rc -eq 5 ] && rc=0
[ $rc2 -eq 5 ] && rc2=0
[ $rc -ne 0 ] && exit $rc
exit $rc2

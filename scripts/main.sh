#!/usr/bin/env bash
# The README's main job: install (idempotent), then a default generation run through the full
# node graph on the simulated Panda (Square D1, skillgen, 50 attempts). Extra arguments go to
# `skillgen generate` (e.g. `bash scripts/main.sh --attempts 5`).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
bash "$ROOT/scripts/bootstrap.sh"
cd "$ROOT"
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"  # loopback unless the user chose
export AMENT_PREFIX_PATH="$ROOT/.venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
exec "$ROOT/.venv/bin/skillgen" generate "$@"

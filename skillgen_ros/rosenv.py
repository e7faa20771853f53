"""Process environment every ROS process of this project starts with.

Loopback-only discovery is the default here (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST); a user who
sets the variable explicitly (e.g. SUBNET on a real robot) keeps their choice. AMENT_PREFIX_PATH
gets the venv prefix so `ament_index_python` finds skillgen_ros and skillgen_interfaces on
pip-only machines, where no setup.bash exists. Imports nothing from ROS.
"""
from __future__ import annotations

import os
import sys


def ros_environment(env: dict | None = None) -> dict:
    """Return (and apply to `env`, default os.environ) the variables a ROS process needs."""
    env = os.environ if env is None else env
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    prefix = sys.prefix
    for var in ("AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH"):
        parts = [p for p in env.get(var, "").split(os.pathsep) if p]
        if prefix not in parts:
            parts.append(prefix)
        env[var] = os.pathsep.join(parts)
    lib = os.path.join(prefix, "lib")
    parts = [p for p in env.get("LD_LIBRARY_PATH", "").split(os.pathsep) if p]
    if lib not in parts:
        env["LD_LIBRARY_PATH"] = os.pathsep.join(parts + [lib])
    return env


# A node is one process among several on the robot computer. OpenMP (open3d) and OpenBLAS (numpy)
# pools spin-wait after each parallel region, and on a small machine those spinning threads take the
# cores the control loop needs: perception burnt a fifth of a core between requests that way.
NODE_THREAD_DEFAULTS = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


def node_environment(env: dict | None = None) -> dict:
    """ros_environment() plus one math thread per node process, unless the caller chose otherwise."""
    env = ros_environment(env)
    for k, v in NODE_THREAD_DEFAULTS.items():
        env.setdefault(k, v)
    return env


def launch_environment(environ) -> dict:
    """The variables a launch file adds to each node (`additional_env` overrides the inherited
    environment, so only what the user left unset): LOCALHOST discovery and one math thread."""
    defaults = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", **NODE_THREAD_DEFAULTS}
    return {k: v for k, v in defaults.items() if not environ.get(k)}


ros_environment()


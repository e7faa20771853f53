"""What every benchmark JSON says about the machine it ran on.

The CPU model matters beyond speed: numba compiles the planning kernels for the host CPU, and a
different instruction set changes the last bits of IK and collision results, which the contact
physics can amplify into a different outcome for a borderline attempt (bench/datagen: one Square
insertion of 200 flipped between two machines with the same code and seeds). Record it so two
runs can be told apart.
"""
from __future__ import annotations

import hashlib
import os
import platform


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def numba_target() -> str:
    """The CPU numba compiles for, as LLVM names it, and a short hash of its feature string."""
    try:
        from llvmlite import binding as llvm

        features = llvm.get_host_cpu_features().flatten()
        return f"{llvm.get_host_cpu_name()} ({hashlib.sha256(features.encode()).hexdigest()[:12]})"
    except Exception:  # noqa: BLE001 -- informational only
        return "unknown"


def machine_info(**extra) -> dict:
    """platform, python, cpus, cpu model, numba's target and the 1/5/15-min load now; `extra` adds
    a bench's own."""
    return {"platform": platform.platform(), "python": platform.python_version(), "cpus": os.cpu_count(),
            "cpu_model": cpu_model(), "numba_target": numba_target(), "load_avg": list(os.getloadavg()), **extra}

"""Compile the planning kernels into numba's on-disk cache (`scripts/bootstrap.sh` runs this).

Why: a cold compile takes about 10 s on a quiet core and several times that on a loaded one. A
planner node that is still compiling cannot act on Ctrl-C (LLVM does not return to Python), so on a
fresh clone the first graph stopped soon after its start had the launcher escalate to SIGTERM (CI,
2026-12-06). With the cache warm the node's start-up loads the kernels in about a second.
"""
from __future__ import annotations

import time


def warm_kernels() -> float:
    """Build what the planner node builds at start-up, plus the batched link poses (the point-cloud
    self filter): every kernel signature a node compiles. Returns the seconds it took."""
    from .collision import CollisionModel
    from .ik import IKSolver
    from .kinematics import PandaKinematics
    from .planner import MotionPlanner

    t0 = time.perf_counter()
    kin = PandaKinematics()
    planner = MotionPlanner(kin, IKSolver(kin, rng=0), CollisionModel(kin))
    planner.warm_up()
    kin.link_poses_batch(0.5 * (kin.lower + kin.upper)[None])
    return time.perf_counter() - t0


if __name__ == "__main__":
    print(f"[bootstrap] planning kernels compiled or loaded from numba's cache in {warm_kernels():.1f} s")

"""Motion planning for the Panda: the paper's retreat -> transit/transfer -> approach.

Public API (docs/planning.md has the method and the numbers):
    kin = PandaKinematics()                      # pinocchio FK, Jacobian, limits
    ik = IKSolver(kin, collision_checker=None)   # TRAC-IK style; ik.solve(pose) -> IKResult
    cm = CollisionModel(kin)                     # fitted spheres vs boxes / cloud / table / self
    cm.set_boxes([Box("cube", T, half_extents)]) # or cm.set_point_cloud(points, self_filter_q=q)
    planner = MotionPlanner(kin, ik, cm)
    res = planner.plan(q, target_pose, Mode.TRANSIT, manipulated="cube")  # -> PlanResult
Imports are lazy so that `from skillgen_ros.core.planning import kinematics` stays light.
"""
from __future__ import annotations

import importlib

_LAZY = {
    "PandaKinematics": "kinematics", "LINKS": "kinematics",
    "IKSolver": "ik", "IKResult": "ik", "IKStatus": "ik",
    "CollisionModel": "collision", "Box": "collision", "AttachedObject": "collision",
    "AllowedContacts": "collision",
    "MotionPlanner": "planner", "PlanResult": "planner", "PlanStatus": "planner", "Mode": "planner",
    "JointTrajectory": "timing", "time_parameterize": "timing",
    "cartesian_line": "phases",
}
__all__ = sorted(_LAZY)


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

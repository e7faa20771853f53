"""Simulated Panda (pybullet): world, torque-level OSC, joint-trajectory tracking, gripper, RGB-D.

Frames (all right-handed, metres, quaternions xyzw):
- world: z up; the Panda base (panda_link0) at the origin; the table top is the plane z = TABLE_Z (-0.092, robosuite's mounting: core/robot.py).
  The robot faces +x; the table spans x 0.16..0.96, y -0.40..0.40; objects live at roughly x 0.31..0.86.
- EE: panda_grasptarget (0.105 m along panda_hand z, between the fingertips); z points out of the
  gripper, the fingers close along its y axis.
- object frames: origin at the centre of the object's bounding box, z up at rest (core/tasks/spec.py).
- camera frames are optical frames (z forward, x right, y down in the image):
  "front" is fixed at FRONT_EYE = (1.35, 0, 0.70) looking at (0.56, 0, -0.07);
  "wrist" is on panda_hand at (0.065, 0, 0.03), optical axis along hand z tilted 20 deg toward the
  fingers, image x along hand y. CameraFrame.T_world_camera maps optical -> world.

`commands` (validation) and `control` (control laws) are pure numpy; `SimWorld` needs pybullet and
is imported lazily so the kinematic mock driver can use the validation without loading pybullet.
"""
from .commands import (Contact, JointTrajectory, TrajectoryCode, TrajectoryError, TrajectoryResult,  # noqa: F401
                       validate_gripper, validate_osc_target, validate_trajectory)

_LAZY = {"SimWorld": "world", "SimConfig": "world", "MockWorld": "mock", "CameraConfig": "camera", "CameraFrame": "camera", "OscGains": "control", "JointGains": "control"}


def __getattr__(name):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(name)

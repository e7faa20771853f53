"""The robot every lane agrees on: pybullet_data's Franka Panda.

One place for the URDF, joint names, the end-effector frame and the limits, so that the sim's
OSC controller, the planner's kinematics and the dataset all mean the same thing by "EE pose".
The end-effector (tool centre point) is `panda_grasptarget`: 0.105 m along panda_hand's z, between
the fingertips. Its z axis points out of the gripper; "retreat" is along -z.
"""
from __future__ import annotations

import os

import numpy as np

ARM_JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))
FINGER_JOINTS = ("panda_finger_joint1", "panda_finger_joint2")
EE_LINK = "panda_grasptarget"
HAND_LINK = "panda_hand"
BASE_LINK = "panda_link0"

# Limits from the URDF (position) and Franka's datasheet (velocity, acceleration, jerk).
Q_LOWER = np.array([-2.9671, -1.8326, -2.9671, -3.1416, -2.9671, -0.0873, -2.9671])
Q_UPPER = np.array([2.9671, 1.8326, 2.9671, 0.0, 2.9671, 3.8223, 2.9671])
V_MAX = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
A_MAX = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])
J_MAX = np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0])
GRIPPER_MAX_WIDTH = 0.08  # metres between the fingers, fully open
CONTROL_HZ = 20.0  # control steps per second (robosuite's control_freq): one osc_target per step

# A comfortable "ready" pose: EE about 0.5 m in front of the base, pointing down.
Q_HOME = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 1.9, 0.785398])

# robosuite's Panda, for comparison (a deviation docs/tasks.md lists; used by bench/datagen/diagnose.py's
# --robosuite-joint-limits experiment): models/assets/robots/panda/robot.xml joint ranges (Franka's datasheet:
# joint 4 never straightens, -0.0698 rad, where pybullet_data's panda.urdf above allows 0.0) and
# models/robots/manipulators/panda_robot.py init_qpos (its EE 18 cm above the table, ours 49 cm).
ROBOSUITE_Q_LOWER = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])
ROBOSUITE_Q_UPPER = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])
ROBOSUITE_Q_HOME = np.array([0.0, np.pi / 16, 0.0, -np.pi / 2 - np.pi / 3, 0.0, np.pi - 0.2, np.pi / 4])

# The robot base (panda_link0) sits at the world origin; the table is robosuite's, mounted as robosuite
# mounts the Panda beside it (robosuite 1.5.2):
# - models/robots/manipulators/panda_robot.py base_xpos_offset["table"] = (-0.16 - table_length / 2, 0, 0):
#   the base is 0.16 + 0.8 / 2 = 0.56 m behind the centre of the 0.8 m table (table_full_size (0.8, 0.8, 0.05),
#   environments/manipulation/nut_assembly.py);
# - the default RethinkMount (models/bases/rethink_mount.py top_offset (0, 0, -0.01); its root body at
#   z -0.922 in models/assets/bases/rethink_mount.xml) puts the base at z 0.922 - 0.01 = 0.912 through
#   RobotModel.set_base_xpos / bottom_offset (models/robots/robot_model.py);
# - NutAssembly / Square put the table top at table_offset z = 0.82, so the top is 0.912 - 0.82 = 0.092 m
#   below the base. (MimicGen's Threading uses table_offset z 0.80, 2 cm lower; we keep one table for all
#   tasks: docs/tasks.md lists it as a deviation.)
ROBOSUITE_BASE_Z = 0.912
ROBOSUITE_TABLE_TOP_Z = 0.82
TABLE_Z = ROBOSUITE_TABLE_TOP_Z - ROBOSUITE_BASE_Z   # -0.092: table top in the world (base) frame
TABLE_FULL_SIZE = (0.8, 0.8, 0.05)                   # robosuite table_full_size (x, y, thickness)
TABLE_CENTER_XY = (0.16 + TABLE_FULL_SIZE[0] / 2, 0.0)  # (0.56, 0): base_xpos_offset["table"] negated


def panda_urdf_path() -> str:
    import pybullet_data  # local import: pure data lookup, no physics client

    return os.path.join(pybullet_data.getDataPath(), "franka_panda", "panda.urdf")

"""What one control step of a recorded source demo holds (the demonstrator's rollout output).

One `DemoStep` per 20 Hz control period: the observation the command was computed from and the
command itself. The CLI turns these into the source bag's messages (joint_states, ee_pose,
gripper_state, sim/ground_truth/object_poses, object_joint_states when the scene has articulated objects,
then osc_target) stamped with the sim time.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np


@dataclass(frozen=True)
class DemoStep:
    time: float  # s since the scene reset
    joint_names: tuple[str, ...]
    joint_positions: np.ndarray  # (J,)
    ee_pose: np.ndarray  # (7,) x y z qx qy qz qw, measured before the command
    gripper_width: float  # m between the fingers
    gripper_grasping: bool
    object_poses: Mapping[str, np.ndarray]  # id -> (7,)
    object_types: Mapping[str, str]  # id -> model name
    target: np.ndarray  # (7,) the OSC target commanded at this step
    gripper_command: float  # -1 open .. +1 closed
    object_joints: Mapping[str, float] = field(default_factory=dict)  # "<id>/<joint>" -> value (Coffee's lid)


@dataclass(frozen=True)
class DemoRollout:
    """A whole demo: its scene, its steps, and whether the sim judged it a success."""

    task: str
    variant: str
    seed: int
    steps: tuple[DemoStep, ...]
    success: bool
    demonstrator_seed: int
    info: Mapping[str, object] = field(default_factory=dict)

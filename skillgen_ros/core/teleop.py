"""What the person teleoperating sees: the live status line, skill progress and the demo's verdict.

Pure (no rclpy): the teleop node feeds it the measured EE pose, gripper state and object poses;
`skillgen demos record` asks `demo_verdict` whether the recorded demo did the task (the task's
own success rule over the bag's last step) before the demo goes where demos are used.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from .geometry import Pose
from .robot import GRIPPER_MAX_WIDTH
from .tasks import SceneState
from .tasks.articulation import initial_joint_values
from .tasks.skill_points import skill_point_name, skill_point_world

KEY_NAMES = {" ": "space (gripper)", "w": "w (+x)", "s": "s (-x)", "a": "a (+y)", "d": "d (-y)", "r": "r (+z)",
             "f": "f (-z)", "u": "u (+roll)", "o": "o (-roll)", "i": "i (+pitch)", "k": "k (-pitch)",
             "j": "j (+yaw)", "l": "l (-yaw)", "]": "] (steps x2)", "[": "[ (steps /2)", "0": "0 (reset target)",
             "h": "h (help)"}


def key_name(key: str) -> str:
    return KEY_NAMES.get(key, repr(key))


class SkillProgress:
    """Which skill's object the hand should go to next, from the gripper's grasp events.

    A skill reached by transit (a free hand) is a grasp: it is done when the gripper starts
    holding something. A skill reached by transfer (carrying) is a placement: done when the
    gripper lets go. A guide for the person, not a verdict (that is `demo_verdict` on `q`).
    """

    def __init__(self, task):
        self.task = task
        self.index = 0
        self._grasping = False

    @property
    def done(self) -> bool:
        return self.index >= len(self.task.skills)

    def update(self, grasping: bool) -> int:
        """Feed the gripper's grasp state; returns the index of the next skill (len(skills) = all done)."""
        grasping = bool(grasping)
        if grasping != self._grasping and not self.done:
            mode = self.task.skills[self.index].mode
            if (grasping and mode == "transit") or (not grasping and mode == "transfer"):
                self.index += 1
        self._grasping = grasping
        return self.index


@dataclass(frozen=True)
class TeleopView:
    """One status-line's worth of state; None fields are not known yet."""

    ee: Pose | None = None
    gripper_width: float | None = None
    grasping: bool = False
    gripper_command: float | None = None
    next_skill: int | None = None
    objects: dict | None = None  # object id -> Pose
    last_key: str = ""


def next_target(task, skill: int | None, objects: dict | None) -> tuple[str, np.ndarray | None]:
    """('square_nut handle', its world point) for the next skill; the point is None without the object's pose."""
    if task is None or skill is None or skill >= len(task.skills):
        return ("all skills done: press q" if task is not None and skill is not None else ""), None
    oid = task.skills[skill].object_id
    label = f"{oid} {skill_point_name(task, skill)}"
    pose = (objects or {}).get(oid)
    return label, (None if pose is None else skill_point_world(task, skill, pose))


def status_line(view: TeleopView, task=None) -> str:
    """'next square_nut handle 0.124 m | gripper 0.080 m open | key w (+x) | EE +0.512 -0.103 +0.201 m
    rpy +180 +0 +90': what the person needs without another window, the most pressing first (a narrow
    terminal cuts the line's end)."""
    parts = []
    label, point = next_target(task, view.next_skill, view.objects)
    if label:
        dist = ("" if point is None or view.ee is None
                else f" {float(np.linalg.norm(point - np.asarray(view.ee.position))):.3f} m")
        parts.append(f"next {label}{dist}")
    if view.gripper_width is None:
        parts.append("gripper ?")
    else:
        state = "GRASPING" if view.grasping else (
            "closed" if view.gripper_width < 0.1 * GRIPPER_MAX_WIDTH else
            "closing" if (view.gripper_command or -1) > 0 else "open")
        parts.append(f"gripper {view.gripper_width:.3f} m {state}")
    parts.append(f"key {key_name(view.last_key) if view.last_key else '-'}")
    if view.ee is None:
        parts.append("EE: waiting for ee_pose")
    else:
        p = view.ee.position
        rpy = Rotation.from_quat(view.ee.quaternion).as_euler("xyz", degrees=True)
        parts.append(f"EE {p[0]:+.3f} {p[1]:+.3f} {p[2]:+.3f} m rpy {rpy[0]:+.0f} {rpy[1]:+.0f} {rpy[2]:+.0f}")
    return " | ".join(parts)


# ---------------------------------------------------------------------------------------- verdict
@dataclass(frozen=True)
class DemoVerdict:
    success: bool
    steps: int
    detail: str


def demo_verdict(path, task) -> DemoVerdict:
    """The task's success rule on the recorded demo's last step (true object poses, EE, gripper command),
    the same rule the sim and generation use (TaskSpec.is_success)."""
    from .skills.bag_demos import read_demo_arrays

    arrays = read_demo_arrays(Path(path))
    return verdict_at(arrays, task, len(arrays.timestamps) - 1)


def verdict_at(arrays, task, k: int) -> DemoVerdict:
    """The success rule on step k of a demo's arrays (DemoArrays)."""
    n = len(arrays.timestamps)
    poses = {oid: Pose(arrays.object_positions[oid][k], arrays.object_quaternions[oid][k])
             for oid in arrays.object_positions}
    missing = sorted({o.id for o in task.objects} - set(poses))
    if missing:
        return DemoVerdict(False, n, f"the demo has no poses of {missing}")
    joints = {name: float(v[k]) for name, v in arrays.object_joints.items()}
    unknown = sorted(key for key in initial_joint_values(task.objects) if key not in joints)
    if unknown:  # a lid's angle is part of the rule: a bag without object_joint_states cannot be judged
        return DemoVerdict(False, n, f"the demo has no values of joints {unknown} (record object_joint_states)")
    state = SceneState(poses, np.asarray(arrays.ee_positions[k], float), float(arrays.gripper[k]), joints)
    ok = task.is_success(state)
    return DemoVerdict(ok, n, f"{task.name}'s success rule on step {k} of {n}: {'met' if ok else 'not met'}")

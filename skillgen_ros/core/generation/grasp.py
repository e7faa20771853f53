"""Where a grasped object is: the paper's rigid-attachment assumption, without ground truth.

Perception sees an object on the table before its grasp skill (Algorithm 1 estimates before each
skill). When the gripper closes, the object stops moving relative to the hand, so its pose from
then on is T_W^O(t) = T_W^E(t) (T_W^E(grasp))^-1 T_W^O(estimate). Transfer planning uses this to
attach the object to the hand and to filter its points out of the obstacle cloud.
"""
from __future__ import annotations

import numpy as np

from ..geometry import Pose, invert


class GraspTracker:
    def __init__(self):
        self._in_hand: dict[str, np.ndarray] = {}  # object id -> T_E^O (object in the EE frame)

    def clear(self) -> None:
        self._in_hand.clear()

    def grasped(self, object_id: str, T_W_O_before: np.ndarray, T_W_E_at_grasp: np.ndarray) -> None:
        self._in_hand = {object_id: invert(np.asarray(T_W_E_at_grasp, float)) @ np.asarray(T_W_O_before, float)}

    def released(self, T_W_E_now: np.ndarray | None = None) -> dict[str, Pose]:
        """Let go; returns where the held object was believed to be at that moment (none without a pose)."""
        out = {} if T_W_E_now is None else {k: Pose.from_matrix(np.asarray(T_W_E_now, float) @ T)
                                              for k, T in self._in_hand.items()}
        self._in_hand.clear()
        return out

    def holding(self) -> str | None:
        return next(iter(self._in_hand), None)

    def object_in_ee(self, object_id: str) -> np.ndarray | None:
        return self._in_hand.get(object_id)

    def pose_now(self, object_id: str, T_W_E_now: np.ndarray) -> Pose | None:
        T = self._in_hand.get(object_id)
        return None if T is None else Pose.from_matrix(np.asarray(T_W_E_now, float) @ T)

    def after_skill(self, gripper_commands, ee_poses, skill_object: str | None,
                    estimates: dict[str, Pose]) -> dict[str, Pose]:
        """After a replayed skill (commands and the EE pose array (n, 7) before each): if the hand
        ends closed on the skill's object, hold it rigidly from CLOSE_PERIODS after the close (the
        fingers take that long); if it ends open, let go. Returns the poses to believe from now on
        for what was let go (where the hand left it), else {}."""
        g = np.asarray(gripper_commands, float)
        k = grasp_step(g)
        if k is None:
            opened, at = np.flatnonzero(g <= 0), None
            if len(opened):  # the state the opening command led to
                at = Pose.from_array(ee_poses[min(opened[0] + 1, len(ee_poses) - 1)]).matrix()
            return self.released(at)
        if skill_object in estimates and k < len(ee_poses):
            settled = Pose.from_array(ee_poses[min(k + CLOSE_PERIODS, len(ee_poses) - 1)]).matrix()
            self.grasped(skill_object, estimates[skill_object].matrix(), settled)
        return {}


def grasp_step(gripper_commands: np.ndarray) -> int | None:
    """Index of the step where the gripper command last switched from open (<= 0) to closed (> 0)
    and stayed closed to the end; None if the hand ends open."""
    g = np.asarray(gripper_commands, float)
    if len(g) == 0 or g[-1] <= 0:
        return None
    opened = np.flatnonzero(g <= 0)
    return int(opened[-1] + 1) if len(opened) else 0


CLOSE_PERIODS = 5  # control periods the fingers take to close on an object


def beliefs_along(estimates: dict, held: tuple[str, np.ndarray] | None, skill_object: str | None,
                  ee_matrices, gripper_commands) -> list[dict]:
    """The robot's belief of the object poses before each step of a commanded sequence, as an env
    tracks it while stepping: a held object (id, T_E^O) follows the hand until the command opens,
    then stays where the hand let it go; the skill's object follows the hand from CLOSE_PERIODS
    after the command closed. `ee_matrices[k]` is the EE pose before step k."""
    tracker, estimates = GraspTracker(), dict(estimates)
    if held is not None:
        tracker.grasped(held[0], held[1], np.eye(4))
    out, last, closing = [], (1.0 if held else -1.0), -1
    for k, T in enumerate(ee_matrices):
        belief = dict(estimates)
        h = tracker.holding()
        if h is not None:
            belief[h] = tracker.pose_now(h, T)
        out.append(belief)
        after = ee_matrices[k + 1] if k + 1 < len(ee_matrices) else T  # where the command of step k leads
        g = float(gripper_commands[k])
        if g > 0 >= last:
            closing = CLOSE_PERIODS
        elif g <= 0 < last:
            estimates.update(tracker.released(after))
            closing = -1
        last = g
        if closing > 0:
            closing -= 1
            if closing == 0 and skill_object in estimates:
                p = estimates[skill_object]
                tracker.grasped(skill_object, p.matrix() if isinstance(p, Pose) else np.asarray(p), after)
    return out


def unaccounted(required, seen, believed) -> list[str]:
    """Required objects perception neither found now nor saw before: those fail the estimate. One it saw
    before keeps its belief (where it was seen or let go) when the view misses it now, e.g. Coffee Prep's mug
    set in the machine's holder under the opened lid; the attempt still needs its skill's object in the result."""
    return [i for i in required if i not in seen and i not in believed]


class LookBeliefs:
    """Which of a look's estimates join the beliefs. An object no skill has acted on yet keeps its most confident
    estimate among the looks so far, until its first skill: a fixture (a drawer, a machine) because its links are
    still at the reset values its model shows, a movable object because nothing moved it. Why the most confident,
    not the latest: a later look is taken from wherever the last skill left the arm, which can hide what breaks an
    object's symmetry (Nut Assembly: the round nut's handle; looks 46 deg off, one octagon step: 24/40 estimated
    attempts with every look taken, 34/40 with this rule, 33/40 with true poses; docs/perception.md), and a
    drawer's half-turn explains its cloud nearly as well as the right pose (keeping the first look's flip sent
    open_drawer to the cabinet's back, IK_FAILED). After its first skill a movable
    object takes every look (it moved), and a fixture's belief is frozen: a look can fit the shut model to an
    opened drawer or lid wrongly (Coffee Prep: 10-23 cm off). An object no skill acts on takes every look."""

    KEEP_UNTOUCHED = True  # False: movable objects take every look (the rule before 2026-12-06; diagnose.py)

    def __init__(self, task):
        """task: a TaskSpec (its objects' is_fixture and its skills' object ids)."""
        self.fixtures = {o.id for o in task.objects if o.is_fixture}
        self.first_skill = {o.id: min((s.index for s in task.skills if s.object_id == o.id), default=-1)
                            for o in task.objects}
        self.confidence: dict[str, float] = {}  # the kept estimate's, for objects not yet acted on

    def update(self, seen, confidence, believed, next_skill: int) -> dict:
        """The beliefs to add from `seen` ({id: pose}) and `confidence` ({id: 0..1}) in the look before skill
        `next_skill`, given the current beliefs."""
        out = {}
        for k, v in seen.items():
            c = float(confidence.get(k, 0.0))
            untouched = next_skill <= self.first_skill.get(k, -1)
            kept = k in self.fixtures or (self.KEEP_UNTOUCHED and untouched)
            if k in believed and kept and (not untouched or c <= self.confidence.get(k, -1.0)):
                continue
            out[k] = v
            if kept:
                self.confidence[k] = c
        return out


def carriable(task: str, object_id: str | None) -> str | None:
    """`object_id` if the hand can carry it, else None: a fixture stays put when the hand closes on one of its
    links (Coffee Prep's drawer pulled by its handle, the machine's lid swung open), so its belief must not
    follow the hand (it did: Coffee Prep's drawer belief ended 23 cm off, the machine's 10 cm)."""
    from ..tasks.suite import get_task

    if not object_id:
        return None
    spec = get_task(task)
    obj = next((o for o in spec.objects if o.id == object_id), None)
    return None if obj is not None and obj.is_fixture else object_id

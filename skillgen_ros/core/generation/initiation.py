"""Alternative initiation states for a skill whose planned-to initiation pose is infeasible.

The paper fails an attempt when the motion planner cannot reach T_W^{E_0'} = T_W^{O'} T_O^{E_0}
(every IK solution collides, or none exists), e.g. when a clutter obstacle stands where the
chosen source demo's hand would be. Two choices leave the skill itself valid and give other
initiation poses for the same scene:

1. the skill object's symmetry: a z4 peg or bin looks the same turned by 90 degrees, so
   T_W^{O'} Rz(k 90) is an equally correct object frame to replay the segment in;
2. another source demo's segment, if the object in the hand (for a transfer skill) was grasped
   the same way in that demo, since its segment assumes that grasp.

`initiation_candidates` lists (demo index, object frame) pairs in the order to try: the selected
one first, so a feasible first choice gives exactly the paper's attempt.
"""
from __future__ import annotations

from typing import Iterator, Sequence

import numpy as np

from ..geometry import Symmetry, rotation_angle
from ..skills.protocols import SkillLike, TaskLike
from ..skills.segment import SourceDemo

CONTINUOUS_YAWS = 8  # a round peg: its continuous symmetry sampled every 45 deg
GRASP_TOL_M = 0.015  # two demos hold the object "the same way" within these
GRASP_TOL_RAD = np.radians(20.0)


def symmetry_frames(T_W_O: np.ndarray, symmetry: str) -> list[np.ndarray]:
    """T_W^{O'} turned about its own z by the symmetry group's other elements (identity excluded)."""
    out = []
    for R in Symmetry.parse(symmetry).rotations(CONTINUOUS_YAWS)[1:]:
        T = np.eye(4)
        T[:3, :3] = R
        out.append(np.asarray(T_W_O, float) @ T)
    return out


def grasp_in_demo(demo: SourceDemo, skill_index: int, held: str) -> np.ndarray | None:
    """T_E^{held} at the end of the last skill before `skill_index` that acted on `held` (its grasp)."""
    prior = [s for s in demo.skills if s.index < skill_index and s.object_id == held]
    if not prior:
        return None
    return np.linalg.inv(max(prior, key=lambda s: s.index).termination)


def same_grasp(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return bool(np.linalg.norm(a[:3, 3] - b[:3, 3]) < GRASP_TOL_M and rotation_angle(a[:3, :3], b[:3, :3]) < GRASP_TOL_RAD)


def initiation_candidates(demos: Sequence[SourceDemo], task: TaskLike, skill: SkillLike, selected: int,
                          T_W_O: np.ndarray, rng: np.random.Generator,
                          limit: int) -> Iterator[tuple[int, np.ndarray]]:
    """Up to `limit` (demo, T_W^{O'}) pairs: the selected demo in the estimated frame, then in the
    object's symmetric frames, then the compatible other demos (random order) likewise."""
    sym = next((getattr(o, "symmetry", "none") for o in task.objects if o.id == skill.object_id), "none")
    frames = [np.asarray(T_W_O, float)] + symmetry_frames(T_W_O, sym)
    held = getattr(skill, "attached_object", None)
    grasp = grasp_in_demo(demos[selected], skill.index, held) if held else None
    others = [int(j) for j in rng.permutation(len(demos)) if j != selected
              and (not held or same_grasp(grasp, grasp_in_demo(demos[j], skill.index, held)))]
    n = 0
    for j in [selected] + others:
        for T in frames:
            if n >= limit:
                return
            n += 1
            yield j, T

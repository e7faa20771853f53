"""The initiation condition I at deployment: where the motion planner takes the hand before pi runs.

- `class` (HSP-Class): the Class head names the source demo that spawned the segment; its
  initiation state T_O^{E_0} is adapted to the object pose perception reports, T_W^{E_0'} =
  T_W^{O'} T_O^{E_0}: the same transform generation uses (core/skills/segment.initiation_in_world).
- `reg` (HSP-Reg): the Reg head's pose, regressed from the last observation (no demos needed).
- `bc`: no initiation; the MimicGen BC-RNN baseline runs pi over the whole episode (rollout.py).
- `tamp` (HSP-TAMP, privileged): the source demo's initiation adapted to the true object pose, the
  demo chosen as generation chooses it (core/generation/selection, random per episode, and
  initiation.initiation_candidates when the first pose is unreachable).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..errors import InvalidInputError
from ..generation.initiation import initiation_candidates
from ..generation.selection import make_strategy
from ..geometry import Pose
from ..skills.segment import SourceDemo
from ..skills.transform import matrix_to_array

MODES = ("class", "reg", "tamp", "bc")  # bc: the MimicGen BC-RNN baseline (no skills; rollout.py)


def check_mode(mode: str) -> str:
    if mode not in MODES:
        raise InvalidInputError(f"unknown initiation mode {mode!r}; known: {list(MODES)}", reason="UNKNOWN_MODE")
    return mode


@dataclass(frozen=True)
class InitiationChoice:
    """Candidate initiation poses (world 4x4) in the order to try, with the source demo of each (-1: none)."""

    poses: tuple[np.ndarray, ...]
    demos: tuple[int, ...]


def _matrix(p) -> np.ndarray:
    if isinstance(p, Pose):
        return p.matrix()
    a = np.asarray(p, float)
    return a if a.shape == (4, 4) else Pose.from_array(a).matrix()


def predict_initiation(mode: str, policy, obs_dict: Mapping, skill, task, demos: Sequence[SourceDemo],
                       object_pose, true_pose=None, previous: int | None = None, rng: np.random.Generator | None = None,
                       candidates: int = 1) -> InitiationChoice:
    """I(o) for `mode`. object_pose: perception's T_W^{O'} of the skill object (class); true_pose:
    its ground-truth pose (tamp); previous: the demo chosen for the prior skill (tamp)."""
    if mode == "reg":
        return InitiationChoice((_matrix(policy.initiation_pose(obs_dict)),), (-1,))
    if mode == "class":
        j = int(policy.initiation_source_demo(obs_dict))
        if not 0 <= j < len(demos):
            raise InvalidInputError(f"the Class head chose source demo {j}, but {len(demos)} are loaded",
                                    reason="BAD_CHECKPOINT")
        return InitiationChoice((demos[j].skill(skill.index).initiation_in_world(_matrix(object_pose)),), (j,))
    check_mode(mode)
    T_W_O = _matrix(true_pose)
    j = make_strategy("random").select(demos, skill.index, T_W_O, previous, rng)
    poses, chosen = [], []
    for k, T in initiation_candidates(demos, task, skill, j, T_W_O, rng, candidates):
        poses.append(demos[k].skill(skill.index).initiation_in_world(T))
        chosen.append(k)
    return InitiationChoice(tuple(poses), tuple(chosen))


def pose7(T: np.ndarray) -> np.ndarray:
    return matrix_to_array(np.asarray(T, float))

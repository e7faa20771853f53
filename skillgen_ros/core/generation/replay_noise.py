"""The paper's Replay-Noise baseline: a whole source demo replayed, with action noise, from its own
initial scene (no object-centric transform, no planner): how much of a demo survives noise alone."""
from __future__ import annotations

import time
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..errors import InvalidInputError
from ..skills.segment import SourceDemo
from ..skills.transform import matrix_to_array
from .episode import StepLabel

if TYPE_CHECKING:
    from .attempt import _Attempt


def check_initial_states(demos: Sequence[SourceDemo]) -> None:
    """Replay-Noise resets the sim to each demo's own scene: every demo needs its scene seed."""
    for d in demos:
        if d.scene_seed is None:
            raise InvalidInputError(f"{d.source}: demo {d.name} has no scene seed, so Replay-Noise cannot "
                                    "reset to its initial state", reason="NO_INITIAL_STATE")


def run_replay_noise(at: "_Attempt") -> None:
    """Pick a demo at random, reset to its scene, replay every step with the run's action noise."""
    j = int(at.rng_select.integers(len(at.demos)))
    demo = at.demos[j]
    at.chosen.append(j)
    at.scene_seed = int(demo.scene_seed)
    at.reset(demo.variant, int(demo.scene_seed))
    skill_of = np.full(demo.num_steps, -1)
    mp = np.ones(demo.num_steps, bool)
    init = {}
    for s in demo.skills:
        skill_of[s.start_step:s.end_step] = s.index
        mp[s.start_step:s.end_step] = False
        init[s.index] = matrix_to_array(demo.ee_poses[s.start_step])
    for m in demo.motions:
        if m.next_skill is not None:
            skill_of[m.start_step:m.end_step] = m.next_skill
    t = time.perf_counter()
    try:
        for k in range(demo.num_steps):
            si = int(skill_of[k])
            lb = StepLabel(bool(mp[k]), si, j, init.get(si, matrix_to_array(demo.ee_poses[0])))
            at._step(demo.action_poses[k], float(demo.gripper[k]), at.cfg.action_noise, lb)
    finally:
        at._timed("skill", t)

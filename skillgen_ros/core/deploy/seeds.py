"""Held-out reset seeds for evaluation rollouts, disjoint from every generation scene seed.

Generation's scene seed of attempt i is SeedSequence(run seed, spawn key (i, 0)) drawn as a
uint32 and shifted right once (core/generation/seeds.scene_seed), so it is always < 2**31.
Rollout i of an evaluation seeded `seed` draws from its own stream (spawn key (i, EVAL_STREAM))
and sets bit 31: it lies in [2**31, 2**32), a range no generation run can produce, whatever the
run seeds. Every simulator here accepts seeds up to 2**32 - 1 (tasks/spec.validate_seed).
"""
from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError

EVAL_STREAM = 100  # spawn-key stream id, apart from generation's STREAMS (0..4)
HELD_OUT_BIT = 1 << 31


def rollout_seed(seed: int, index: int) -> int:
    """The reset seed of evaluation rollout `index` of an evaluation seeded `seed`."""
    if int(seed) < 0 or int(index) < 0:
        raise InvalidInputError(f"seed and rollout index must be >= 0, got {seed}, {index}", reason="INVALID_PARAMETER")
    ss = np.random.SeedSequence(entropy=int(seed), spawn_key=(int(index), EVAL_STREAM))
    return int(HELD_OUT_BIT | (int(ss.generate_state(1, dtype=np.uint32)[0]) >> 1))


def rollout_rng(seed: int, index: int, stream: int) -> np.random.Generator:
    """A generator for one purpose of one rollout (HSP-TAMP's source-demo choice, sampling)."""
    ss = np.random.SeedSequence(entropy=int(seed), spawn_key=(int(index), EVAL_STREAM, int(stream)))
    return np.random.Generator(np.random.PCG64(ss))


def is_held_out(reset_seed: int) -> bool:
    return bool(int(reset_seed) & HELD_OUT_BIT)

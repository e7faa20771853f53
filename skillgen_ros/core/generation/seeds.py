"""Per-attempt seeds: attempt i of a run depends only on (run seed, i).

Derived with numpy's SeedSequence (spawn key = attempt index, then a stream id), so attempts
are statistically independent, any subset can run in any process or machine, and merging
shards gives the same attempts as one long run. The scene seed depends on (run seed, index)
only, so every method sees the same scenes for the same run seed.
"""
from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError

STREAMS = {"scene": 0, "selection": 1, "noise": 2, "augmentation": 3, "initiation": 4, "subtasks": 5}


def _check(run_seed: int, index: int) -> None:
    if int(run_seed) < 0 or int(index) < 0:
        raise InvalidInputError(f"seed and attempt index must be >= 0, got {run_seed}, {index}",
                                reason="INVALID_PARAMETER")


def attempt_seed_sequence(run_seed: int, index: int, stream: str = "scene") -> np.random.SeedSequence:
    _check(run_seed, index)
    if stream not in STREAMS:
        raise InvalidInputError(f"unknown seed stream {stream!r}; known: {sorted(STREAMS)}")
    return np.random.SeedSequence(entropy=int(run_seed), spawn_key=(int(index), STREAMS[stream]))


def scene_seed(run_seed: int, index: int) -> int:
    """The reset seed for attempt `index`: a non-negative 31-bit int every simulator accepts."""
    return int(attempt_seed_sequence(run_seed, index, "scene").generate_state(1, dtype=np.uint32)[0] >> 1)


def attempt_rng(run_seed: int, index: int, stream: str) -> np.random.Generator:
    """An independent generator for one purpose (selection, noise, augmentation) of one attempt."""
    return np.random.Generator(np.random.PCG64(attempt_seed_sequence(run_seed, index, stream)))


def shard_indices(first_index: int, attempts: int, shard: int, num_shards: int) -> range:
    """Attempt indices of one shard: round-robin, so shards finish at about the same time."""
    if num_shards < 1 or not (0 <= shard < num_shards) or attempts < 0:
        raise InvalidInputError(f"bad shard {shard}/{num_shards} of {attempts} attempts", reason="INVALID_PARAMETER")
    return range(first_index + shard, first_index + attempts, num_shards)

"""Source-demo selection strategies (paper Appendix "Reference Skill Segment Selection").

`random`: the paper's default - a source demo drawn uniformly for the first skill and kept for
the rest of the episode. `random_per_skill`: drawn anew for each skill. `nearest_neighbor`:
MimicGen's nearest_neighbor_object - rank the source demos by the distance between the skill
object's pose before the skill in the source and in the new scene (position metres *
pos_weight + rotation angle radians * rot_weight), then draw uniformly among the nn_k closest.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import InvalidInputError
from ..skills.segment import SourceDemo


class SelectionStrategy(Protocol):
    def select(self, demos: Sequence[SourceDemo], skill_index: int, object_pose: np.ndarray,
               previous: int | None, rng: np.random.Generator) -> int:
        """Index into `demos` for this skill; `previous` is the choice for the prior skill, if any."""


def _require(demos: Sequence[SourceDemo]) -> None:
    if not demos:
        raise InvalidInputError("no source demos to select from", reason="NO_SOURCE_DEMOS")


@dataclass(frozen=True)
class RandomPerEpisode:
    def select(self, demos, skill_index, object_pose, previous, rng) -> int:
        _require(demos)
        return int(previous) if previous is not None else int(rng.integers(len(demos)))


@dataclass(frozen=True)
class RandomPerSkill:
    def select(self, demos, skill_index, object_pose, previous, rng) -> int:
        _require(demos)
        return int(rng.integers(len(demos)))


def pose_distance(T_a: np.ndarray, T_b: np.ndarray, pos_weight: float = 1.0, rot_weight: float = 1.0) -> float:
    """pos_weight * ||p_a - p_b|| + rot_weight * geodesic angle(R_a, R_b)."""
    dp = float(np.linalg.norm(T_a[:3, 3] - T_b[:3, 3]))
    ang = float(Rotation.from_matrix(T_a[:3, :3].T @ T_b[:3, :3]).magnitude())
    return pos_weight * dp + rot_weight * ang


@dataclass(frozen=True)
class NearestNeighborObject:
    pos_weight: float = 1.0
    rot_weight: float = 1.0
    nn_k: int = 3

    def __post_init__(self):
        if self.nn_k < 1 or self.pos_weight < 0 or self.rot_weight < 0:
            raise InvalidInputError(f"bad nearest-neighbour parameters {self}", reason="INVALID_PARAMETER")

    def select(self, demos, skill_index, object_pose, previous, rng) -> int:
        _require(demos)
        d = np.array([pose_distance(demo.skill(skill_index).object_pose, np.asarray(object_pose),
                                    self.pos_weight, self.rot_weight) for demo in demos])
        order = np.argsort(d, kind="stable")[: min(self.nn_k, len(demos))]
        return int(order[rng.integers(len(order))])


STRATEGIES: dict[str, Callable[..., SelectionStrategy]] = {
    "random": RandomPerEpisode,
    "random_per_skill": RandomPerSkill,
    "nearest_neighbor": NearestNeighborObject,
}
# Other spellings users and the ReplaySkill action's comment use for the same strategies.
ALIASES = {"nearest": "nearest_neighbor", "nearest_neighbour": "nearest_neighbor"}


def strategy_help() -> str:
    """The names `--selection` accepts, for help texts (from the registry, so they cannot drift)."""
    return ", ".join(sorted(STRATEGIES)) + " (" + ", ".join(f"{a} = {n}" for a, n in sorted(ALIASES.items())) + ")"


def make_strategy(name: str, **params) -> SelectionStrategy:
    """Strategy by registry name; an unknown name raises UNKNOWN_SELECTION listing the known ones."""
    try:
        factory = STRATEGIES[ALIASES.get(name, name)]
    except KeyError:
        raise InvalidInputError(f"unknown selection strategy {name!r}; known: {strategy_help()}",
                                reason="UNKNOWN_SELECTION") from None
    try:
        return factory(**params)
    except TypeError as e:
        raise InvalidInputError(f"selection {name!r}: {e}", reason="INVALID_PARAMETER") from e

"""Algorithm profiles: the paper's Algorithm 1 as published, or this project's improved version.

`paper` runs what the paper describes (Algorithm 1; Appendix "Data Generation Details"), so its
success rates compare with the paper's table:
- one initiation pose per skill: a planner answer that T_W^{E_0'} (or an augmented draw) is
  unreachable fails the attempt (initiation_candidates = 1; initiation.py's retries are ours);
- no release moves (release.py's unjam/follow/clear): the hand only holds while it opens;
- no planner extras (MotionPlanner.plan `extras`: the fixture back-out, the null-space escape,
  the shortened / self-motion retreat): retreat -> transit/transfer -> approach only;
- success is task success, as the paper counts it: the execution-collision filter
  (EXECUTION_COLLISION, the in-process env's robot-touched-another-object check) is off,
  because the paper's rates count every attempt whose task succeeded. (The graph env never
  reports such collisions; with the filter off both paths count alike.)

Both plan with the paper's retreat/approach contact rule (MotionPlanner.plan `movable`: the hand may
touch any manipulated object there, a held object anything).

`skillgen_ros` (the default for users) keeps all of these on: better data, and its own columns in
bench/datagen, never mixed with the paper's. The MimicGen baseline (mimicgen.py) is the same under
both profiles: it has no planner, no initiation candidates and no release.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..errors import InvalidInputError


@dataclass(frozen=True)
class AlgorithmProfile:
    name: str
    initiation_candidates: int  # initiation poses tried per skill (initiation.py); 1 = fail at once
    release_moves: bool  # release.py's unjam / follow / clear before a planned motion
    planner_extras: bool  # MotionPlanner.plan(extras=...), PlanToPose.extras in graph mode
    check_collisions: bool  # fail an attempt whose planned motion touched another object


PROFILES: dict[str, AlgorithmProfile] = {
    "paper": AlgorithmProfile("paper", initiation_candidates=1, release_moves=False, planner_extras=False,
                              check_collisions=False),
    "skillgen_ros": AlgorithmProfile("skillgen_ros", initiation_candidates=6, release_moves=True,
                                     planner_extras=True, check_collisions=True),
}
DEFAULT_PROFILE = "skillgen_ros"
PROFILE_NAMES: tuple[str, ...] = tuple(PROFILES)


def get_profile(name: str) -> AlgorithmProfile:
    """The named profile; an unknown name raises UNKNOWN_PROFILE listing the known ones."""
    try:
        return PROFILES[name or DEFAULT_PROFILE]
    except KeyError:
        raise InvalidInputError(f"unknown profile {name!r}; known: {', '.join(PROFILE_NAMES)}",
                                reason="UNKNOWN_PROFILE") from None

"""datagen's reader of the driver's `state_history` service (srv StateHistory).

The driver keeps every control period it published (measured joint and finger positions, the
world's object poses: a simulator's ground truth, and articulated objects' joint values) in a
bounded ring. datagen asks for a stretch of it once per planned motion and once per skill, and once
per attempt for the remaining stamps, instead of reading a topic in the control loop (every reader
costs the driver a delivery per period). The joint values are what the in-process env records as
Observation.object_joints ({"coffee_machine/lid": rad}: obs/<id>_joints), period by period.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
from builtin_interfaces.msg import Time

from skillgen_interfaces.srv import StateHistory
from skillgen_ros.core.errors import SkillGenError


def ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def to_time(t_ns: int) -> Time:
    return Time(sec=int(t_ns) // 1_000_000_000, nanosec=int(t_ns) % 1_000_000_000)


class DriverHistory:
    """`call(client, request)` answers a request or raises (RosGraphEnv._call with its timeout)."""

    def __init__(self, client, call: Callable):
        self.client, self._call = client, call
        self._last: tuple[tuple[int, int], dict] | None = None  # _rows' last answer (a past span never changes)

    def ready(self) -> bool:
        return self.client.service_is_ready()

    def periods(self, after_ns: int, until_ns: int = 0) -> dict:
        """The periods stamped in (after, until] (until 0: to the newest) as arrays."""
        resp = self._call(self.client, StateHistory.Request(after=to_time(after_ns), until=to_time(until_ns)))
        if not resp.success:
            raise SkillGenError(f"state_history: {resp.reason_code}: {resp.message}", reason=resp.reason_code)
        n, k, j = len(resp.stamps), len(resp.object_ids), len(resp.joint_names)
        return {"stamps": [ns(t) for t in resp.stamps], "kinds": np.asarray(resp.kinds, int),
                "q": np.asarray(resp.joint_positions, float).reshape(n, 7),
                "fingers": np.asarray(resp.finger_positions, float).reshape(n, 2), "ids": list(resp.object_ids),
                "poses": np.asarray(resp.object_poses, float).reshape(n, k, 7),
                "joint_names": list(resp.joint_names), "joints": np.asarray(resp.object_joints, float).reshape(n, j)}

    @staticmethod
    def _truth(h: dict, i: int) -> dict | None:
        return dict(zip(h["ids"], h["poses"][i])) if h["ids"] else None

    @staticmethod
    def _joints(h: dict, i: int) -> dict[str, float]:
        """Period i's articulated joint values ({} in a scene without any, as world.object_joints())."""
        return {n: float(v) for n, v in zip(h["joint_names"], h["joints"][i])}

    def _rows(self, stamps: list[int]) -> tuple[dict, list[int]]:
        span = (min(stamps) - 1, max(stamps))  # stamps already published: the span's periods are final
        if self._last is None or self._last[0] != span:
            self._last = (span, self.periods(*span))
        h = self._last[1]
        row = {t: i for i, t in enumerate(h["stamps"])}
        missing = [t for t in stamps if t not in row]
        if missing:
            raise SkillGenError(f"state_history lacks {len(missing)} of the {len(stamps)} periods asked for "
                                f"(first: {missing[0]} ns)", reason="TIMEOUT")
        return h, [row[t] for t in stamps]

    def true_object_poses(self, stamps) -> dict[int, dict[str, np.ndarray]]:
        """stamp -> id -> (7,) the true poses of those periods; NO_GROUND_TRUTH where the driver has none."""
        if not self.client.wait_for_service(timeout_sec=5.0):  # a real robot's driver has no such service
            raise SkillGenError("the driver offers no state_history: no ground truth", reason="NO_GROUND_TRUTH")
        h, idx = self._rows(list(stamps))
        if not h["ids"]:
            raise SkillGenError("the driver reports no object poses: no ground truth", reason="NO_GROUND_TRUTH")
        return {h["stamps"][i]: self._truth(h, i) for i in idx}

    def object_joints(self, stamps) -> dict[int, dict[str, float]]:
        """stamp -> name -> value: articulated objects' joint values of those periods ({} for each in a scene
        without any); none at all ({}) from a driver without state_history (a real robot's). Right after
        true_object_poses of the same stamps this is answered from that call's periods."""
        if not stamps or not self.ready():
            return {}
        h, idx = self._rows(list(stamps))
        return {h["stamps"][i]: self._joints(h, i) for i in idx}

    def skill_periods(self, stamps: list[int]) -> dict:
        """A replayed skill's steps (by the stamps skill_replay read): stamps_ns, each finger's
        position (the result carries only the width), articulated joint values and, where the driver
        knows them, true poses."""
        h, idx = self._rows(stamps)
        out = {"stamps_ns": stamps, "fingers": h["fingers"][idx], "object_joints": [self._joints(h, i) for i in idx]}
        if h["ids"]:
            out["true_object_poses"] = [self._truth(h, i) for i in idx]
        return out

    def trajectory_periods(self, after_ns: int) -> list[tuple]:
        """(stamp ns, arm q, fingers, true poses or None, joint values) of each execute_trajectory period
        after `after_ns`."""
        h = self.periods(after_ns)
        return [(h["stamps"][i], h["q"][i], h["fingers"][i], self._truth(h, i), self._joints(h, i))
                for i in np.flatnonzero(h["kinds"] == StateHistory.Response.TRAJECTORY)]

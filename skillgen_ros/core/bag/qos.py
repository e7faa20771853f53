"""Offered-QoS profiles as rosbag2 metadata version 9 writes them: complete dicts, every key present.

rosbag2's YAML reader (and rosbags' AnyReader) read all nine keys of each profile and fail on a
missing one (issue 19: the first shipped bags lacked deadline, lifespan and liveliness). Every
profile that reaches a bag goes through `complete_profile`, which fills what a caller left out
with the DDS defaults. Pure: no rclpy (nodes/bag_qos.py converts rclpy QoSProfile objects).
"""
from __future__ import annotations

from typing import Iterable, Mapping

from skillgen_ros.core.errors import BagError

# RMW_DURATION_INFINITE as rosbag2 (Jazzy) writes it. rosbag2 also reads Foxy's {2^31-1, 2^32-1}
# as infinite; both are accepted on input.
INFINITE = {"sec": 9223372036, "nsec": 854775807}
FOXY_INFINITE = {"sec": 2147483647, "nsec": 4294967295}
INFINITE_NS = 0x7FFFFFFFFFFFFFFF

DEFAULT_PROFILE: dict = {
    "history": "keep_last",
    "depth": 10,
    "reliability": "reliable",
    "durability": "volatile",
    "deadline": dict(INFINITE),
    "lifespan": dict(INFINITE),
    "liveliness": "automatic",
    "liveliness_lease_duration": dict(INFINITE),
    "avoid_ros_namespace_conventions": False,
}
PROFILE_KEYS = tuple(DEFAULT_PROFILE)
DURATION_KEYS = ("deadline", "lifespan", "liveliness_lease_duration")
_POLICIES = {
    "history": ("keep_last", "keep_all", "system_default", "unknown"),
    "reliability": ("reliable", "best_effort", "system_default", "best_available", "unknown"),
    "durability": ("volatile", "transient_local", "system_default", "best_available", "unknown"),
    "liveliness": ("automatic", "manual_by_topic", "system_default", "best_available", "unknown"),
}


def duration_dict(ns: int) -> dict:
    """Nanoseconds -> {'sec', 'nsec'}; negative or >= INFINITE_NS is infinite."""
    if ns < 0 or ns >= INFINITE_NS:
        return dict(INFINITE)
    return {"sec": ns // 10**9, "nsec": ns % 10**9}


def _duration(value, key: str) -> dict:
    if not isinstance(value, Mapping) or set(value) != {"sec", "nsec"} or not all(
            isinstance(value[k], int) and not isinstance(value[k], bool) and value[k] >= 0
            for k in ("sec", "nsec")):
        raise BagError(f"QoS {key} must be {{sec: int >= 0, nsec: int >= 0}}, got {value!r}", "BAD_QOS")
    return {"sec": int(value["sec"]), "nsec": int(value["nsec"])}


def complete_profile(profile: Mapping) -> dict:
    """A full v9 profile: `profile`'s values over DEFAULT_PROFILE; BagError BAD_QOS if a value is wrong."""
    if not isinstance(profile, Mapping):
        raise BagError(f"a QoS profile must be a mapping, got {type(profile).__name__}", "BAD_QOS")
    unknown = set(profile) - set(PROFILE_KEYS)
    if unknown:
        raise BagError(f"unknown QoS keys {sorted(unknown)}; rosbag2 v9 has {list(PROFILE_KEYS)}", "BAD_QOS")
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in DEFAULT_PROFILE.items()}
    for key, value in profile.items():
        if key in _POLICIES:
            value = str(value).lower()
            if value not in _POLICIES[key]:
                raise BagError(f"QoS {key} '{value}' is not one of {_POLICIES[key]}", "BAD_QOS")
        elif key in DURATION_KEYS:
            value = _duration(value, key)
        elif key == "depth":
            if not isinstance(value, int) or isinstance(value, bool) or value < 0:
                raise BagError(f"QoS depth must be an int >= 0, got {value!r}", "BAD_QOS")
        elif key == "avoid_ros_namespace_conventions":
            value = bool(value)
        out[key] = value
    return out


def complete_profiles(profiles: Iterable[Mapping]) -> tuple[dict, ...]:
    return tuple(complete_profile(p) for p in profiles)


def missing_keys(profile: Mapping) -> list[str]:
    """Keys a rosbag2 v9 reader needs that `profile` lacks (what `bag reindex` repairs)."""
    return [k for k in PROFILE_KEYS if k not in profile] if isinstance(profile, Mapping) else list(PROFILE_KEYS)

"""QoS <-> rosbag2 metadata (v9 dicts), shared by the recorder and player shells.

rosbag2 stores each publisher's offered QoS per topic; the recorder subscribes so it matches
every publisher (best effort if any publisher is best effort, transient local only if all are),
and the player republishes with the recorded reliability and durability.
"""
from __future__ import annotations

from typing import Iterable, Mapping

from rclpy.duration import Duration
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile,
                       ReliabilityPolicy)

from skillgen_ros.core.bag.qos import complete_profile, duration_dict


def _dur(d: Duration) -> dict:
    return duration_dict(d.nanoseconds)


def _policy_name(value) -> str:
    name = getattr(value, "name", str(value))
    return name.lower()


def qos_to_dict(q: QoSProfile) -> dict:
    """One offered QoS profile in rosbag2 metadata version 9 form (all keys, core/bag/qos.py)."""
    return complete_profile({
        "history": _policy_name(q.history),
        "depth": int(q.depth),
        "reliability": _policy_name(q.reliability),
        "durability": _policy_name(q.durability),
        "deadline": _dur(q.deadline),
        "lifespan": _dur(q.lifespan),
        "liveliness": _policy_name(q.liveliness),
        "liveliness_lease_duration": _dur(q.liveliness_lease_duration),
        "avoid_ros_namespace_conventions": bool(q.avoid_ros_namespace_conventions),
    })


def subscription_qos(offered: Iterable[QoSProfile], depth: int) -> QoSProfile:
    """A subscription QoS compatible with every offered profile (rosbag2's adaptation rule)."""
    offered = list(offered)
    best_effort = any(q.reliability == ReliabilityPolicy.BEST_EFFORT for q in offered)
    latched = bool(offered) and all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
        liveliness=LivelinessPolicy.AUTOMATIC)


def playback_qos(recorded: Iterable[Mapping], depth: int = 10) -> QoSProfile:
    """Publisher QoS for replay: recorded reliability/durability where known, reliable otherwise."""
    recorded = [r for r in recorded if isinstance(r, Mapping)]
    rel = {str(r.get("reliability", "")).lower() for r in recorded}
    dur = {str(r.get("durability", "")).lower() for r in recorded}
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=ReliabilityPolicy.BEST_EFFORT if rel == {"best_effort"} else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if dur == {"transient_local"} else DurabilityPolicy.VOLATILE)

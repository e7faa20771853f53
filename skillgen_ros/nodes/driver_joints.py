"""The driver's `object_joint_states` topic: articulated objects' joint values (a lid's hinge angle, a
drawer's opening) as sensor_msgs/JointState, one name per joint, "<object id>/<joint name>"
(core/tasks/articulation.joint_key), positions in rad / m.

Latched like the ground-truth poses (reliable, transient local, depth 1), so a reader that joins late
(the planner, datagen) still gets the current values; published on every state the driver publishes
while someone reads it, and always on a reset, with no names when the scene has no articulated object.
In the sim the values are the simulator's; the kinematic mock keeps the reset's initial values.
The reader side (`ObjectJointReader`) is the planner's: it poses articulated obstacles at these values.
"""
from __future__ import annotations

from typing import Callable

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from skillgen_ros.nodes import convert
from skillgen_ros.nodes.latest import LatestMessage

TOPIC = "object_joint_states"
QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class ObjectJointStates:
    def __init__(self, make_pub: Callable, frame: str):
        """make_pub(type, topic, qos) creates a publisher on the driver node."""
        self.pub, self.frame = make_pub(convert.JointState, TOPIC, QOS), frame

    def publish(self, world, stamp, force: bool) -> None:
        """This period's values (skipped without a reader unless `force`, e.g. on a reset)."""
        if world.scene is None or not (force or self.pub.get_subscription_count()):
            return
        values = world.object_joints()
        self.pub.publish(convert.joint_state(list(values), list(values.values()), frame_id=self.frame, stamp=stamp))


class ObjectJointReader:
    """The newest `object_joint_states` as {name: value}, read on demand (nodes/latest.py): a node that
    needs the values once per request is not woken every period."""

    def __init__(self, owner):
        self._latest, self._first = LatestMessage(owner, convert.JointState, TOPIC, QOS), True

    def values(self) -> dict[str, float] | None:
        """The latest values (the first call waits up to 1 s for the latched message); None if none came."""
        m = self._latest.latest(1.0 if self._first else 0.0)
        self._first = False
        if m is None or len(m.name) != len(m.position):
            return None
        return {str(n): float(v) for n, v in zip(m.name, m.position)}

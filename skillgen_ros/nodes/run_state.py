"""Where a generation attempt is, on topics Foxglove's State Transitions panel plots
(docs/foxglove/skillgen.json): `run/attempt` (Int32, the attempt index), `run/skill`
(Int32, the skill being reached or replayed; -1 outside skills) and `run/stage` (String:
reset, perception, motion, skill, success). Latched, so a late viewer or recorder sees the state."""
from __future__ import annotations

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Int32, String

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
TOPICS = ("run/attempt", "run/skill", "run/stage")


class RunState:
    def __init__(self, node: Node):
        self._attempt = node.create_publisher(Int32, TOPICS[0], LATCHED)
        self._skill = node.create_publisher(Int32, TOPICS[1], LATCHED)
        self._stage = node.create_publisher(String, TOPICS[2], LATCHED)
        self._last: tuple | None = None

    def attempt(self, index: int) -> None:
        self._attempt.publish(Int32(data=int(index)))
        self.stage("reset", -1)

    def stage(self, stage: str, skill: int | None = None) -> None:
        """Publish what changed (a stage repeated per step costs nothing)."""
        last_stage, last_skill = self._last or ("", -2)
        skill = last_skill if skill is None else int(skill)
        if skill != last_skill:
            self._skill.publish(Int32(data=skill))
        if stage != last_stage:
            self._stage.publish(String(data=stage))
        self._last = (stage, skill)

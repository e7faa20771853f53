"""The hsp node's GenerationEnv: RosGraphEnv plus what deployment needs and generation's graph path does not.

RosGraphEnv (graph_env.py) is datagen's view of the graph and is used unchanged; this subclass
only adds:
- grasp tracking from the node's own OSC commands (datagen's skills run in skill_replay, whose
  results feed the tracker; here pi streams the commands), by the rule SimGenerationEnv applies in
  step(): 5 periods after the hand closes on the skill's object, it is rigidly attached;
- `true_object_poses()` from `sim/ground_truth/object_poses` of the current period (HSP-TAMP's
  privileged checks, and the grasp tracker's reference when `grasp_reference` is ground_truth,
  as SimGenerationEnv uses the sim's poses when its perception is ground truth);
- a motion's observations, one per control period the driver executed (counted from the sim
  time of joint_states before and after it), as SimGenerationEnv returns one per executed period:
  RosGraphEnv samples the planned trajectory instead, which can be a period short (the driver's
  settling period), and then a graph rollout counts one step fewer than the same rollout in-process;
- readiness without skill_replay, and deploying on the scene the driver already holds.
"""
from __future__ import annotations

import time

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from skillgen_interfaces.msg import ObjectPoseArray, SceneObject
from skillgen_ros.core.errors import SkillGenError
from skillgen_ros.core.generation.grasp import carriable
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.tasks import get_task
from skillgen_ros.nodes import convert
from skillgen_ros.nodes.graph_env import RosGraphEnv
from skillgen_ros.nodes.latest import LatestMessage

CLOSING_PERIODS = 5  # as SimGenerationEnv._track_grasp: periods for the fingers to close
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _stamp(m) -> tuple[int, int]:
    return (m.header.stamp.sec, m.header.stamp.nanosec)


def _seconds(m) -> float:
    return m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec


def per_period(observations: list, periods: int) -> list:
    """`periods` observations: the planned samples, held at the last planned one for periods the
    driver spent settling (or cut short), ending on the measured final state."""
    if periods < 1 or periods == len(observations) or len(observations) < 2:
        return observations
    planned, final = observations[:-1], observations[-1]
    return [planned[min(k, len(planned) - 1)] for k in range(periods - 1)] + [final]


class HspGraphEnv(RosGraphEnv):
    def __init__(self, node, timeouts: dict, grasp_reference: str = "ground_truth", **kw):
        super().__init__(node, timeouts, **kw)
        self.grasp_reference = grasp_reference
        # created now, not on first use: in lockstep a reader matched mid-rollout would wait for a period
        # the driver only runs on the next command
        self._truth = LatestMessage(node, ObjectPoseArray, "sim/ground_truth/object_poses", LATCHED)
        self._last_gripper, self._closing = -1.0, -1

    def reset(self, task: str, variant: str, seed: int):
        resp = super().reset(task, variant, seed)
        self._last_gripper, self._closing = -1.0, -1
        return resp

    def adopt_current_scene(self, task: str) -> None:
        """Deploy on whatever the driver holds: the task's objects without poses (perception finds
        them), the planner unseeded (there is no reset seed)."""
        spec = get_task(task)
        self.task = task
        self.scene_objects = [SceneObject(id=o.id, type=o.type, mesh_uri=o.mesh_path, half_extents=list(o.half_extents),
                                          is_fixture=o.is_fixture) for o in spec.objects]
        if task != self._task_sent:
            self.task_pub.publish(String(data=task))
            self._task_sent = task
        self._plan_seed, self._plans = None, 0
        self._estimates = {}
        self.grasps.clear()
        self._moved = True  # frames from before this goal may be stale: capture first
        joints = self._joints.latest()  # this goal is a scene of its own: fixtures may have moved since the last
        self._scene_stamp = joints.header.stamp if joints is not None else None
        self._last_gripper, self._closing = -1.0, -1

    def wait_ready_for_deploy(self, timeout: float) -> list[str]:
        """The servers a rollout needs (no skill_replay); names still missing after `timeout`."""
        end = time.monotonic() + timeout
        missing = []
        for cli, name in ((self.reset_cli, "reset_scene"), (self.success_cli, "task_success"),
                          (self.estimate_cli, "estimate_poses"), (self.plan_cli, "plan_to_pose")):
            if not cli.wait_for_service(timeout_sec=max(0.1, end - time.monotonic())):
                missing.append(name)
        return missing

    def true_object_poses(self) -> dict[str, Pose]:
        """The sim's true poses of the period of the newest joint_states (privileged; sim only)."""
        joints = self._joints.latest()
        floor = _stamp(joints) if joints is not None else (0, 0)
        m = self._truth.wait_for(lambda m: m is not None and _stamp(m) >= floor, self.t["state"])
        if m is None:
            raise SkillGenError("no sim/ground_truth/object_poses for the current period (a real robot has none: "
                                "HSP-TAMP is a sim-only reference)", reason="PERCEPTION_FAILED")
        return {o.id: convert.pose_from_msg(o.pose) for o in m.objects}

    def plan_and_execute(self, target: Pose, mode: str, attached: str | None):
        before = self._joints.latest()
        status, obs = super().plan_and_execute(target, mode, attached)
        after = self._joints.latest()
        if obs and before is not None and after is not None:
            obs = per_period(list(obs), int(round((_seconds(after) - _seconds(before)) / self.dt)))
        return status, obs

    def step(self, target: Pose, gripper: float):
        obs = super().step(target, gripper)
        return self.observe() if self._track_command(float(gripper), obs) else obs

    def _track_command(self, gripper: float, obs) -> bool:
        """SimGenerationEnv._track_grasp over the command stream; True if the tracker changed."""
        changed = False
        if gripper > 0 >= self._last_gripper:
            self._closing = CLOSING_PERIODS
        elif gripper <= 0 < self._last_gripper:
            changed = self.grasps.holding() is not None
            self.grasps.released()
            self._closing = -1
        self._last_gripper = gripper
        if self._closing > 0:
            self._closing -= 1
            obj = carriable(self.task, self._skill_object)  # a fixture's link does not carry the fixture
            if self._closing == 0 and obj:
                poses = self.true_object_poses() if self.grasp_reference == "ground_truth" else self._estimates
                if obj in poses:
                    self.grasps.grasped(obj, poses[obj].matrix(), obs.ee_matrix())
                    changed = True
        return changed

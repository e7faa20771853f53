"""skill_replay node: the `replay_skill` action.

Loads annotated source demos (bags) per task, picks one (given index or selection strategy),
transforms the skill segment into the current object frame (T_W^A' = T_W^O' T_O^A), turns each
absolute target into a normalized delta-pose action from the current EE pose with
N(0,1)*action_noise on the pose dims (gripper copied), and streams the commanded pose as
`osc_target`, one per control period: after each command it waits for the driver's next
`ee_pose` (a newer stamp), which in lockstep mode is exactly one sim step and in real-time mode
one controller period. Feedback every step (at most feedback_hz per wall second: every step in real
time, rate-limited in lockstep); the result carries every executed step so datagen
can write the dataset.

The step loop is the graph's hot path (one round trip per control period), so the node runs on a
SingleThreadedExecutor and the action is a coroutine that awaits the next ee_pose: no thread
pool, no busy wait set (a MultiThreadedExecutor spun a whole core here while a goal blocked).

Parameters (params/skill_replay.yaml): demos_dir, action_noise, step_timeout, frame_id, feedback_hz.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from geometry_msgs.msg import PoseStamped
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import JointState

from skillgen_interfaces.action import ReplaySkill
from skillgen_interfaces.msg import OscTarget
from skillgen_ros.core.errors import SkillGenError
from skillgen_ros.core.geometry import Pose, validate_pose
from skillgen_ros.core.generation.selection import make_strategy
from skillgen_ros.core.skills.actions import make_action
from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos
from skillgen_ros.core.skills.replay import plan_replay
from skillgen_ros.core.skills.transform import matrix_to_array
from skillgen_ros.core.tasks import get_task
from skillgen_ros.nodes import convert
from skillgen_ros.nodes.feedback import FeedbackThrottle
from skillgen_ros.nodes.runtime import run_node


class SkillReplayNode(Node):
    def __init__(self):
        super().__init__("skill_replay")
        self.declare_parameter("demos_dir", "bags")
        self.declare_parameter("action_noise", 0.05)
        self.declare_parameter("step_timeout", 5.0)
        self.declare_parameter("frame_id", "world")
        self.declare_parameter("feedback_hz", 20.0)
        self._demos: dict[tuple[str, str], list] = {}
        self._ee: PoseStamped | None = None
        self._ee_count = 0
        self._waiter: tuple[int, Future] | None = None  # (ee count to exceed, future the goal awaits)
        self._deadline = float("inf")
        self._q = np.zeros(7)
        self._width = 0.0
        self.create_subscription(PoseStamped, "ee_pose", self._on_ee, 10)
        self.create_subscription(JointState, "joint_states", self._on_joints, 10)  # arm + fingers
        self.osc_pub = self.create_publisher(OscTarget, "osc_target", 10)
        self._busy = False
        self.server = ActionServer(self, ReplaySkill, "replay_skill", self._execute,
                                   goal_callback=self._on_goal, cancel_callback=lambda _g: CancelResponse.ACCEPT)
        self.create_timer(0.1, self._on_watchdog)

    # -- state (all callbacks run on the one executor thread: no locks)
    def _on_ee(self, msg: PoseStamped):
        self._ee = msg
        self._ee_count += 1
        if self._waiter is not None and self._ee_count > self._waiter[0]:
            self._resolve(msg)

    def _resolve(self, value) -> None:
        _after, fut = self._waiter
        self._waiter = None
        if not fut.done():
            fut.set_result(value)

    def _on_watchdog(self):
        if self._waiter is not None and time.monotonic() > self._deadline:
            self._resolve(None)

    def _on_joints(self, msg: JointState):
        if len(msg.position) >= 7:
            self._q = np.array(msg.position[:7])
        if len(msg.position) >= 9:
            self._width = float(msg.position[7] + msg.position[8])  # finger joints: half widths

    async def _wait_ee(self, after: int, timeout: float) -> PoseStamped | None:
        """The first ee_pose after the `after`-th one, or None after `timeout` s (watchdog)."""
        if self._ee_count > after:
            return self._ee
        fut = Future()
        self._waiter, self._deadline = (after, fut), time.monotonic() + timeout
        return await fut

    # -- action
    def _on_goal(self, goal: ReplaySkill.Goal):
        return GoalResponse.REJECT if self._busy else GoalResponse.ACCEPT

    def demos_for(self, task: str, directory: str):
        d = directory or str(Path(self.get_parameter("demos_dir").value) / task)
        key = (task, d)
        if key not in self._demos:
            paths = expand_bag_paths([d])
            if not paths:
                raise SkillGenError(f"no source demo bags under {d}", reason="NO_SOURCE_DEMOS")
            self._demos[key] = load_source_demos(paths, get_task(task))
        return self._demos[key]

    async def _execute(self, goal_handle):
        self._busy = True
        try:
            return await self._replay(goal_handle)
        finally:
            self._busy = False

    async def _replay(self, goal_handle):
        g = goal_handle.request
        res = ReplaySkill.Result()

        def finish(ok: bool, reason: str, message: str):
            res.success, res.reason, res.message = ok, reason, message
            if ok:
                goal_handle.succeed()
            else:
                goal_handle.abort()
            return res

        try:
            demos = self.demos_for(g.task, g.source_demos)
            obj = validate_pose(*convert.pose_arrays_from_msg(g.object_pose), "object_pose")
            T_W_O = obj.matrix()
            rng = np.random.default_rng(int(g.seed))
            if g.source_demo >= 0:
                if g.source_demo >= len(demos):
                    return finish(False, "BAD_DEMO_INDEX", f"source_demo {g.source_demo} >= {len(demos)} demos")
                j = int(g.source_demo)
            else:
                j = make_strategy(g.selection or "random").select(demos, int(g.skill_index), T_W_O, None, rng)
            seg = demos[j].skill(int(g.skill_index))
        except SkillGenError as e:
            return finish(False, e.reason, str(e.args[0]))
        res.source_demo = j
        sigma = float(g.action_noise) if g.action_noise >= 0 else float(self.get_parameter("action_noise").value)
        timeout = float(self.get_parameter("step_timeout").value)
        frame = str(self.get_parameter("frame_id").value)
        feedback = FeedbackThrottle(float(self.get_parameter("feedback_hz").value))
        ee = self._ee
        if ee is None:
            ee = await self._wait_ee(0, timeout)
            if ee is None:
                return finish(False, "TIMEOUT", "no ee_pose from the driver")
        plan = plan_replay(seg, T_W_O, convert.pose_from_msg(ee.pose).matrix(), recovery=bool(g.recovery))
        actions, abs_, ees, qs, widths = [], [], [], [], []
        n = len(plan.targets)
        for k in range(n):
            if goal_handle.is_cancel_requested:
                goal_handle.canceled()
                res.reason, res.message = "CANCELED", f"canceled at step {k}"
                return res
            count, ee = self._ee_count, self._ee
            current = convert.pose_from_msg(ee.pose).matrix()
            noise = 0.0 if plan.recovery[k] else sigma
            a, commanded = make_action(plan.targets[k], current, float(plan.gripper[k]), noise, rng)
            msg = OscTarget()
            msg.header.frame_id = frame
            msg.header.stamp = self.get_clock().now().to_msg()
            msg.pose = convert.pose_to_msg(Pose.from_matrix(commanded))
            msg.gripper = float(plan.gripper[k])
            actions.append(a)
            abs_.append(np.concatenate([matrix_to_array(commanded), [plan.gripper[k]]]))
            ees.append(matrix_to_array(current))
            qs.append(self._q.copy())
            widths.append(self._width)
            self.osc_pub.publish(msg)
            if await self._wait_ee(count, timeout) is None:
                self._fill(res, actions, abs_, ees, qs, widths, plan.recovery[:k + 1])
                return finish(False, "TIMEOUT", f"driver did not step within {timeout} s at step {k}")
            if feedback.due(k == n - 1):
                goal_handle.publish_feedback(ReplaySkill.Feedback(
                    step=k + 1, total_steps=n, stage="recovery" if plan.recovery[k] else "skill"))
        self._fill(res, actions, abs_, ees, qs, widths, plan.recovery)
        return finish(True, "OK", f"replayed skill {g.skill_index} of demo {j} ({n} steps)")

    @staticmethod
    def _fill(res, actions, abs_, ees, qs, widths, recovery):
        res.steps = len(actions)
        res.actions = np.asarray(actions, float).reshape(-1).tolist()
        res.actions_abs = np.asarray(abs_, float).reshape(-1).tolist()
        res.ee_poses = np.asarray(ees, float).reshape(-1).tolist()
        res.joint_positions = np.asarray(qs, float).reshape(-1).tolist()
        res.gripper_widths = [float(w) for w in widths]
        res.recovery_steps = [bool(r) for r in recovery]


def main(args=None) -> int:
    return run_node(SkillReplayNode, args, executor="single")


if __name__ == "__main__":
    sys.exit(main())

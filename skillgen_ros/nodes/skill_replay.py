"""skill_replay node: the `replay_skill` action.

Loads annotated source demos (bags) per task, picks one (given index or selection strategy),
transforms the skill segment into the current object frame (T_W^A' = T_W^O' T_O^A), turns each
absolute target into a normalized delta-pose action from the current EE pose with
N(0,1)*action_noise on the pose dims (gripper copied), and streams the commanded pose as
`osc_target`, one per control period: after each command it waits for the driver's next
`joint_states`, which in lockstep mode is exactly one sim step and in real-time mode one
controller period. The current EE pose is forward kinematics (pinocchio) of those joints, as
robot_state_publisher would give it: one topic closes the loop, so the driver sends one message
per period to this node instead of two (every reader of a topic costs the publisher a delivery).
Feedback every step (at most feedback_hz per wall second: every step in real time, rate-limited in
lockstep); the result carries every executed step, with the stamp of the joint state it started
from, so datagen can write the dataset (and look up the sim's true object poses of those periods).

The step loop is the graph's hot path (one round trip per control period), so the node runs on a
SingleThreadedExecutor and the action is a coroutine that awaits the next joint state: no thread
pool, no busy wait set (a MultiThreadedExecutor spun a whole core here while a goal blocked).

Service `~/load_demos` loads a task's demos ahead of a run (datagen calls it before the first attempt).
Parameters (params/skill_replay.yaml): demos_dir, action_noise, step_timeout, frame_id, feedback_hz.
"""
from __future__ import annotations

import sys
import time
import traceback
from pathlib import Path

import numpy as np
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import JointState

from skillgen_interfaces.action import ReplaySkill
from skillgen_interfaces.msg import OscTarget
from skillgen_interfaces.srv import LoadDemos
from skillgen_ros.core import validation as V
from skillgen_ros.core.errors import InvalidInputError, ParameterError, SkillGenError
from skillgen_ros.core.geometry import Pose, validate_pose
from skillgen_ros.core.generation.selection import make_strategy
from skillgen_ros.core.planning.kinematics import PandaKinematics
from skillgen_ros.core.robot import ARM_JOINTS, FINGER_JOINTS
from skillgen_ros.core.skills.actions import make_action
from skillgen_ros.core.skills.bag_demos import SourceDemoCache, expand_bag_paths
from skillgen_ros.core.skills.replay import plan_replay
from skillgen_ros.core.skills.transform import matrix_to_array
from skillgen_ros.core.tasks import get_task
from skillgen_ros.nodes import convert
from skillgen_ros.nodes.feedback import RESULT_TIMEOUT_S, FeedbackThrottle
from skillgen_ros.nodes.graph_calls import RESEND_AFTER_S
from skillgen_ros.nodes.runtime import run_node


MAX_ACTION_NOISE = 1.0  # sigma on normalized actions; beyond it a replay is noise, not the skill


class SkillReplayNode(Node):
    def __init__(self):
        super().__init__("skill_replay")
        self.executor_kind = "single"  # the step loop is a coroutine (see the module docstring)
        self.declare_parameter("demos_dir", "bags")
        self.declare_parameter("action_noise", 0.05)
        self.declare_parameter("step_timeout", 5.0)
        self.declare_parameter("frame_id", "world")
        self.declare_parameter("feedback_hz", 20.0)
        try:
            V.finite("action_noise", self.get_parameter("action_noise").value, 0.0, MAX_ACTION_NOISE)
            V.finite("step_timeout", self.get_parameter("step_timeout").value, 0.0, 3600.0, lo_open=True)
            V.finite("feedback_hz", self.get_parameter("feedback_hz").value, 0.0, 1000.0)  # 0 = every step
        except InvalidInputError as e:
            raise ParameterError(str(e.args[0])) from None
        self._demos = SourceDemoCache()  # (bag files, task) -> source demos
        self._kin = PandaKinematics()
        self._state: JointState | None = None  # newest joint_states with every arm joint
        self._state_count = 0
        self._index: tuple[tuple, list[int], list[int]] | None = None  # (names, arm idx, finger idx)
        self._waiter: tuple[int, Future] | None = None  # (state count to exceed, future the goal awaits)
        self._deadline = float("inf")
        self._resend, self._resend_at = None, float("inf")  # the osc_target a step waits on (resent)
        self.create_subscription(JointState, "joint_states", self._on_joints, 10)  # arm + fingers
        self.osc_pub = self.create_publisher(OscTarget, "osc_target", 10)
        self._busy = False
        self.server = ActionServer(self, ReplaySkill, "replay_skill", self._execute,
                                   goal_callback=self._on_goal, cancel_callback=lambda _g: CancelResponse.ACCEPT,
                                   result_timeout=RESULT_TIMEOUT_S)
        self.create_timer(0.1, self._on_watchdog)
        self.create_service(LoadDemos, "~/load_demos", self._on_load_demos)

    # -- state (all callbacks run on the one executor thread: no locks)
    def _on_joints(self, msg: JointState):
        names = tuple(msg.name)
        if self._index is None or self._index[0] != names:
            pos = {n: i for i, n in enumerate(names)}
            if not all(j in pos for j in ARM_JOINTS):
                return  # e.g. a gripper-only joint_states: not a robot state
            self._index = (names, [pos[j] for j in ARM_JOINTS], [pos[j] for j in FINGER_JOINTS if j in pos])
        if self._state is not None and msg.header.stamp == self._state.header.stamp:
            return  # the driver's answer to a resent target it had applied: the state we have
        self._state = msg
        self._state_count += 1
        if self._waiter is not None and self._state_count > self._waiter[0]:
            self._resolve(msg)

    def _unpack(self, msg: JointState) -> tuple[np.ndarray, float, np.ndarray]:
        """(arm q, gripper width, T_W_EE by FK) of a joint_states message _on_joints accepted."""
        _names, arm, fingers = self._index
        q = np.array([msg.position[i] for i in arm])
        width = float(sum(msg.position[i] for i in fingers)) if len(fingers) == 2 else 0.0  # half widths
        return q, width, self._kin.fk(q)

    def _resolve(self, value) -> None:
        _after, fut = self._waiter
        self._waiter = None
        if not fut.done():
            fut.set_result(value)

    def _on_watchdog(self):
        if self._waiter is not None and time.monotonic() > self._deadline:
            self._resolve(None)
        elif self._waiter is not None and self._resend is not None and time.monotonic() > self._resend_at:
            self._resend_at = time.monotonic() + RESEND_AFTER_S  # no state yet: the same target again
            self.osc_pub.publish(self._resend)  # (same stamp: applied once, graph_calls._await_step)
            self.get_logger().warning("osc_target sent again: no state within "
                                      f"{RESEND_AFTER_S:g} s", throttle_duration_sec=5.0)

    async def _wait_state(self, after: int, timeout: float) -> JointState | None:
        """The first joint state after the `after`-th one, or None after `timeout` s (watchdog)."""
        if self._state_count > after:
            return self._state
        fut = Future()
        self._waiter, self._deadline = (after, fut), time.monotonic() + timeout
        self._resend_at = time.monotonic() + RESEND_AFTER_S
        return await fut

    # -- action
    def _on_goal(self, goal):
        """Busy: reject. An empty task is a readiness probe (skillgen_ros/answered.py): reject, run nothing."""
        return GoalResponse.REJECT if self._busy or not goal.task else GoalResponse.ACCEPT

    def demos_for(self, task: str, directory: str):
        d = directory or str(Path(self.get_parameter("demos_dir").value) / task)
        paths = expand_bag_paths([d])
        if not paths:
            raise SkillGenError(f"no source demo bags under {d}", reason="NO_SOURCE_DEMOS")
        return self._demos.load(paths, get_task(task))  # reloaded when a bag's files change

    def _on_load_demos(self, req: LoadDemos.Request, res: LoadDemos.Response) -> LoadDemos.Response:
        try:
            get_task(V.name("task", req.task))
            if len(req.source_demos) > V.MAX_PATH:
                raise InvalidInputError("source_demos is longer than a path can be", reason="INVALID_PATH")
            res.demos = len(self.demos_for(req.task, req.source_demos))
        except SkillGenError as e:
            res.success, res.reason_code, res.message = False, e.reason, str(e.args[0])
            return res
        res.success, res.reason_code, res.message = True, "OK", f"{res.demos} source demos for {req.task}"
        return res

    async def _execute(self, goal_handle):
        self._busy = True
        try:
            return await self._replay(goal_handle)
        except Exception as e:  # noqa: BLE001 -- a bug answers with a reason; the node keeps serving
            self.get_logger().error(f"replay_skill failed: {traceback.format_exc()}")
            goal_handle.abort()
            return ReplaySkill.Result(success=False, reason="INTERNAL_ERROR", message=f"{type(e).__name__}: {e}")
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
            get_task(V.name("task", g.task))  # UNKNOWN_TASK before any file is looked for
            V.name("selection", g.selection, allow_empty=True)
            if len(g.source_demos) > V.MAX_PATH:
                raise InvalidInputError("source_demos is longer than a path can be", reason="INVALID_PATH")
            # negative = the node's action_noise (ReplaySkill.action); NaN/inf refused, not defaulted
            sigma = V.or_default("action_noise", g.action_noise, float(self.get_parameter("action_noise").value),
                                 MAX_ACTION_NOISE)
            obj = validate_pose(*convert.pose_arrays_from_msg(g.object_pose), "object_pose")
            V.finite("object_pose distance from the base", np.linalg.norm(obj.position), 0.0, V.MAX_REACH,
                     reason="INVALID_POSE")
            demos = self.demos_for(g.task, g.source_demos)
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
        timeout = float(self.get_parameter("step_timeout").value)
        frame = str(self.get_parameter("frame_id").value)
        feedback = FeedbackThrottle(float(self.get_parameter("feedback_hz").value))
        state = self._state
        if state is None:
            state = await self._wait_state(0, timeout)
            if state is None:
                return finish(False, "TIMEOUT", "no joint_states from the driver")
        q, width, current = self._unpack(state)
        plan = plan_replay(seg, T_W_O, current, recovery=bool(g.recovery))
        actions, abs_, ees, qs, widths, stamps = [], [], [], [], [], []
        n = len(plan.targets)
        for k in range(n):
            if goal_handle.is_cancel_requested:  # the steps done so far still come back
                self._fill(res, actions, abs_, ees, qs, widths, stamps, plan.recovery[:k])
                goal_handle.canceled()
                res.reason, res.message = "CANCELED", f"canceled at step {k}"
                return res
            count = self._state_count
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
            qs.append(q)
            widths.append(width)
            stamps.append(state.header.stamp)
            self.osc_pub.publish(msg)
            self._resend = msg
            state = await self._wait_state(count, timeout)
            self._resend = None
            if state is None:
                self._fill(res, actions, abs_, ees, qs, widths, stamps, plan.recovery[:k + 1])
                return finish(False, "TIMEOUT", f"driver did not step within {timeout} s at step {k}")
            q, width, current = self._unpack(state)
            if feedback.due(k == n - 1):
                goal_handle.publish_feedback(ReplaySkill.Feedback(
                    step=k + 1, total_steps=n, stage="recovery" if plan.recovery[k] else "skill"))
        self._fill(res, actions, abs_, ees, qs, widths, stamps, plan.recovery)
        return finish(True, "OK", f"replayed skill {g.skill_index} of demo {j} ({n} steps)")

    @staticmethod
    def _fill(res, actions, abs_, ees, qs, widths, stamps, recovery):
        res.steps = len(actions)
        res.actions = np.asarray(actions, float).reshape(-1).tolist()
        res.actions_abs = np.asarray(abs_, float).reshape(-1).tolist()
        res.ee_poses = np.asarray(ees, float).reshape(-1).tolist()
        res.joint_positions = np.asarray(qs, float).reshape(-1).tolist()
        res.gripper_widths = [float(w) for w in widths]
        res.recovery_steps = [bool(r) for r in recovery]
        res.stamps = list(stamps)


def main(args=None) -> int:
    return run_node(SkillReplayNode, args)


if __name__ == "__main__":
    sys.exit(main())

"""The driver's actions: execute_trajectory and gripper_command (a mixin of DriverNode).

One goal at a time (the robot does one thing); a goal advances the world itself, period by period,
publishing every state as the timer would, with feedback throttled to feedback_hz. Bad goals are
aborted with an error code and string (INVALID_GOAL ...) and the driver keeps its previous command.
"""
from __future__ import annotations

import time

from rclpy.action import GoalResponse

from skillgen_interfaces.action import ExecuteTrajectory, Gripper
from skillgen_interfaces.srv import StateHistory
from skillgen_ros.core import validation as V
from skillgen_ros.core.errors import SkillGenError
from skillgen_ros.core.sim.commands import TrajectoryCode, TrajectoryError
from skillgen_ros.nodes import convert
from skillgen_ros.nodes.feedback import FeedbackThrottle

GRIPPER_WAIT_S = 1.5
MAX_TRAJECTORY_POINTS = 200_000  # about an hour at 50 Hz: more is a mistake, not a motion
# A planned motion lasts seconds; a longer trajectory is a mistake, and in lockstep (one thread) the
# driver answers nothing else while it runs one (the fuzz bench found a 1 h goal blocking it 60 s+).
MAX_TRAJECTORY_SECONDS = 60.0  # ten times the longest planned motion


class DriverActions:
    """Expects DriverNode's world, lock, busy, hz, param(), _advance(), _report(), _wait_period()."""

    def _one_goal(self, _goal) -> GoalResponse:
        return GoalResponse.REJECT if self.busy else GoalResponse.ACCEPT

    def _exec_traj(self, handle) -> ExecuteTrajectory.Result:
        result = ExecuteTrajectory.Result()
        try:
            tol = V.finite("goal_tolerance", handle.request.goal_tolerance)  # <= 0: the default; NaN refused
            if len(handle.request.trajectory.points) > MAX_TRAJECTORY_POINTS:
                raise SkillGenError(f"{len(handle.request.trajectory.points)} trajectory points; at most "
                                    f"{MAX_TRAJECTORY_POINTS} are accepted", "INVALID_GOAL")
            names, times, pos, vel = convert.trajectory_from_msg(handle.request.trajectory)
            if len(times) and not float(times[-1]) <= MAX_TRAJECTORY_SECONDS:
                raise SkillGenError(f"trajectory lasts {float(times[-1]):.0f} s; at most {MAX_TRAJECTORY_SECONDS:.0f} s "
                                    "are accepted", "INVALID_GOAL")
            with self.lock:
                self.world.start_trajectory(names, times, pos, vel, tol)
                self.busy = True
        except TrajectoryError as e:
            self._report(e)
            handle.abort()
            result.error_code, result.error_string = int(e.code), str(e)
            return result
        except SkillGenError as e:
            self._report(e)
            handle.abort()
            result.error_code, result.error_string = int(TrajectoryCode.INVALID_GOAL), str(e)
            return result
        except (ValueError, TypeError) as e:  # ragged point arrays in the message
            handle.abort()
            result.error_code, result.error_string = int(TrajectoryCode.INVALID_GOAL), f"INVALID_GOAL: {e}"
            return result
        t0, k, fb = time.monotonic(), 0, ExecuteTrajectory.Feedback()
        feedback = FeedbackThrottle(float(self.param("feedback_hz")))
        try:
            while True:
                if handle.is_cancel_requested:
                    with self.lock:
                        self.world.step(self.world.ee_pose(), None)  # hold where it is
                    handle.canceled()
                    result.error_code, result.error_string = int(TrajectoryCode.PATH_TOLERANCE_VIOLATED), "canceled"
                    return result
                out = {}
                try:
                    self._advance(lambda: out.update(r=self.world.step_trajectory()), StateHistory.Response.TRAJECTORY)
                except SkillGenError as e:  # e.g. reset_scene while the trajectory ran
                    self._report(e)
                    handle.abort()
                    result.error_code, result.error_string = int(TrajectoryCode.PATH_TOLERANCE_VIOLATED), str(e)
                    return result
                progress, q_des, done = out["r"]
                if feedback.due(done is not None):
                    fb.progress, fb.desired_positions = float(progress), [float(v) for v in q_des]
                    fb.actual_positions = [float(v) for v in self.world.joint_positions()]
                    handle.publish_feedback(fb)
                if done is not None:
                    result.error_code, result.error_string = int(done.code), done.message
                    handle.succeed() if done.code == TrajectoryCode.SUCCESSFUL else handle.abort()
                    return result
                k += 1
                self._wait_period(t0, k)
        finally:
            self.busy = False

    def _exec_gripper(self, handle) -> Gripper.Result:
        result, g = Gripper.Result(), handle.request
        try:
            V.finite("gripper position", g.position, reason="INVALID_GOAL")  # out of range: clamped below
            V.finite("gripper max_effort", g.max_effort, reason="INVALID_GOAL")  # <= 0: the default 20 N
            with self.lock:
                self.world.gripper_to(g.position, g.max_effort if g.max_effort > 0 else 20.0)
                self.busy = True
        except SkillGenError as e:
            self._report(e)
            handle.abort()
            result.width = float(self.world.gripper_width())
            return result
        t0, k, last = time.monotonic(), 0, -1.0
        try:
            while k < GRIPPER_WAIT_S * self.hz:
                self._advance(lambda: self.world.idle(1), StateHistory.Response.GRIPPER)
                width = float(self.world.gripper_width())
                handle.publish_feedback(Gripper.Feedback(width=width))
                if abs(width - last) < 2e-4:
                    break
                last, k = width, k + 1
                self._wait_period(t0, k)
        finally:
            self.busy = False
        width = float(self.world.gripper_width())
        result.width, result.reached_goal = width, abs(width - min(max(g.position, 0.0), 0.08)) < 0.005
        result.stalled = not result.reached_goal
        handle.succeed()
        return result

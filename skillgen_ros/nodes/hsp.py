"""hsp node: deploys a trained Hybrid Skill Policy through the `run_task` action (paper Algorithm 2).

A RunTask goal names a task, a checkpoint and the initiation mode (class, reg, tamp; bc runs the
MimicGen BC-RNN baseline over the whole episode); a non-empty `variant` first resets the scene
(task/variant/seed) so the rollout is the same as an in-process one with that reset seed. The node
runs the pure executor (core/deploy/rollout.run_rollout) over the graph (nodes/hsp_env.HspGraphEnv:
perception's `estimate_poses`, the planner's `plan_to_pose` with execution on the driver, pi's OSC
targets on `osc_target` one control period each, the driver's `task_success`), publishes feedback
(skill index, stage: initiation / motion / policy / termination, control step) and answers with a
reason code. Bad input is an answer, never a crash: UNKNOWN_TASK, UNKNOWN_MODE, BAD_CHECKPOINT,
NO_SOURCE_DEMOS, UNKNOWN_VARIANT; a goal while a rollout runs is rejected (logged: BUSY), and an
empty task is a readiness probe (rejected, as datagen's; see answered.py).

Parameters (params/hsp.yaml): demos_dir, device, collision_source, grasp_reference, max_steps,
skill_max_steps, initiation_candidates, feedback_hz, torch_threads and the per-call timeouts.
"""
from __future__ import annotations

import json
import os
import sys
import threading
import traceback

from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node

from skillgen_interfaces.action import RunTask
from skillgen_interfaces.srv import PlanToPose
from skillgen_ros.core.deploy import DeployConfig, run_rollout
from skillgen_ros.core.deploy.initiation import MODES, check_mode
from skillgen_ros.core.deploy.loading import load_policy
from skillgen_ros.core import validation as V
from skillgen_ros.core.errors import InvalidInputError, ParameterError, SkillGenError
from skillgen_ros.core.tasks import get_task
from skillgen_ros.nodes.feedback import FeedbackThrottle
from skillgen_ros.nodes.hsp_env import HspGraphEnv
from skillgen_ros.nodes.runtime import run_node

TIMEOUTS = {"reset": 30.0, "perception": 20.0, "plan": 10.0, "execute": 60.0, "skill": 120.0, "state": 10.0}


MAX_STEPS = 100_000  # control steps per rollout (about 80 minutes at 20 Hz)


class HspNode(Node):
    def __init__(self):
        super().__init__("hsp")
        defaults = {"demos_dir": "bags", "device": "cpu", "collision_source": "scene", "grasp_reference": "ground_truth",
                    "default_mode": "class", "max_steps": 1500, "skill_max_steps": 400, "initiation_candidates": 6,
                    "feedback_hz": 20.0, "torch_threads": 1, "driver_node": "sim_driver",
                    **{f"timeout_{k}": v for k, v in TIMEOUTS.items()}}
        for k, v in defaults.items():
            self.declare_parameter(k, v)
        p = {k: self.get_parameter(k).value for k in defaults}
        if p["collision_source"] not in ("scene", "point_cloud"):
            raise ParameterError(f"collision_source must be scene or point_cloud, got {p['collision_source']!r}")
        if p["grasp_reference"] not in ("ground_truth", "estimate"):
            raise ParameterError(f"grasp_reference must be ground_truth or estimate, got {p['grasp_reference']!r}")
        try:
            check_mode(p["default_mode"])
            self.defaults = DeployConfig(mode=p["default_mode"], max_steps=int(p["max_steps"]),
                                         skill_max_steps=int(p["skill_max_steps"]),
                                         initiation_candidates=int(p["initiation_candidates"]))
        except SkillGenError as e:
            raise ParameterError(str(e.args[0])) from None
        timeouts = {k: float(p[f"timeout_{k}"]) for k in TIMEOUTS}
        if not all(0 < v < float("inf") for v in timeouts.values()) or int(p["torch_threads"]) < 1 \
                or not 0 <= float(p["feedback_hz"]) < float("inf"):
            raise ParameterError(f"timeouts must be finite and > 0, feedback_hz finite and >= 0, torch_threads >= 1, got {timeouts}, {p['torch_threads']}")
        import torch

        torch.set_num_threads(int(p["torch_threads"]))  # one core per policy step; the same sums as in-process
        self.p = p
        src = PlanToPose.Request.SOURCE_POINT_CLOUD if p["collision_source"] == "point_cloud" else PlanToPose.Request.SOURCE_SCENE
        self.env = HspGraphEnv(self, timeouts, grasp_reference=p["grasp_reference"], collision_source=src,
                               driver_node=str(p["driver_node"]))
        self._busy = threading.Lock()
        self._cache: dict = {}  # (checkpoint, mtime, task, mode) -> (policy, demos)
        self.server = ActionServer(self, RunTask, "run_task", self._execute, goal_callback=self._on_goal,
                                   cancel_callback=lambda _g: CancelResponse.ACCEPT,
                                   callback_group=MutuallyExclusiveCallbackGroup())
        self.get_logger().info(f"hsp ready: action 'run_task' (modes {', '.join(MODES)}, device {p['device']})")

    def _on_goal(self, goal):
        if not goal.task:
            self.get_logger().info("run_task goal with an empty task rejected (clients probe readiness this way)")
            return GoalResponse.REJECT
        if not self._busy.acquire(blocking=False):  # reserved here, released when the accepted goal ends
            self.get_logger().warning("run_task goal rejected: a rollout is in progress (BUSY)")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _execute(self, handle):
        try:
            return self._run(handle)
        except Exception as e:  # noqa: BLE001 -- a bug answers with a reason; the node keeps serving
            self.get_logger().error(f"run_task failed: {traceback.format_exc()}")
            handle.abort()
            return RunTask.Result(success=False, reason="INTERNAL_ERROR", message=f"{type(e).__name__}: {e}")
        finally:
            self._busy.release()

    def _policy(self, checkpoint: str, task: str, mode: str):
        key = (checkpoint, os.path.getmtime(checkpoint) if os.path.isfile(checkpoint) else None, task, mode)
        if key not in self._cache:
            self._cache.clear()
            self._cache[key] = load_policy(checkpoint, task, mode, str(self.p["device"]), str(self.p["demos_dir"]))
        return self._cache[key]

    def _run(self, handle) -> RunTask.Result:
        g = handle.request
        res = RunTask.Result()
        mode = g.initiation_mode or self.defaults.mode
        try:
            V.name("task", g.task)
            V.name("variant", g.variant, allow_empty=True)
            V.name("initiation_mode", mode)
            if not g.checkpoint or len(g.checkpoint) > V.MAX_PATH:
                raise InvalidInputError("checkpoint must be a path of at most "
                                        f"{V.MAX_PATH} characters", reason="BAD_CHECKPOINT")
            if int(g.max_steps) > MAX_STEPS:
                raise InvalidInputError(f"max_steps must be <= {MAX_STEPS}, got {g.max_steps}", reason="INVALID_PARAMETER")
            spec = get_task(g.task)
            check_mode(mode)
            policy, demos = self._policy(g.checkpoint, g.task, mode)
            missing = self.env.wait_ready_for_deploy(float(self.p["timeout_state"]))
            if missing:
                raise SkillGenError(f"not available: {', '.join(missing)}", reason="GRAPH_NOT_READY")
            cfg = DeployConfig(**{**self.defaults.__dict__, "mode": mode,
                                  "max_steps": int(g.max_steps) or self.defaults.max_steps})
            if g.variant:
                self.env.reset(g.task, g.variant, int(g.seed))
            else:
                self.env.adopt_current_scene(g.task)
            throttle = FeedbackThrottle(float(self.p["feedback_hz"]))
            last = [None]

            def progress(k: int, stage: str, step: int) -> None:
                if throttle.due(final=(k, stage) != last[0]):  # every stage change, steps rate-limited
                    handle.publish_feedback(RunTask.Feedback(skill_index=k, stage=stage, step=step))
                last[0] = (k, stage)

            r = run_rollout(self.env, policy, spec, int(g.seed), None, cfg, demos, on_progress=progress)
        except SkillGenError as e:
            res.success, res.reason, res.message = False, e.reason, str(e.args[0])
            self.get_logger().error(f"run_task: {e}")
            handle.abort()
            return res
        res.success, res.reason, res.message = r.success, r.reason.value, r.message
        res.steps, res.ee_poses = r.steps, [float(v) for v in r.ee_trajectory.reshape(-1)]
        res.skill_log = json.dumps([s.__dict__ for s in r.skills])
        res.inference_ms_per_step = r.inference_ms_per_step
        self.get_logger().info(f"run_task {g.task} [{mode}]: {r.reason.value} after {r.steps} steps: {r.message}")
        handle.succeed() if r.success else handle.abort()
        return res


def main(args=None) -> int:
    return run_node(HspNode, args)


if __name__ == "__main__":
    sys.exit(main())

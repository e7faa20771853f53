"""datagen node: the user's trigger for generation (`generate` action, `run_attempt` service).

Each attempt runs Algorithm 1 over the graph (see graph_env.RosGraphEnv): reset_scene ->
estimate_poses -> per skill: plan_to_pose (transit/transfer, retreat+approach, executed on the
driver) then replay_skill -> task_success -> keep (demo.hdf5) or drop (failed.hdf5, with reason).
The run loop, dataset, report and video are core code (core/generation/session.py); this node
maps the action goal onto a RunRequest, streams feedback (attempts, successes, rate, ETA) and can
record the session through the recorder's services.

Parameters (params/datagen.yaml): demos_dir, output_root, collision_source, action_noise,
observation_source (ground_truth: the sim's true object poses in obs/<id>_pose; estimate: a real robot), profile
(the algorithm profile, core/generation/profile.py: paper or skillgen_ros; a goal's `profile` overrides it),
release.* (how the hand lets go before a planned motion: core/generation/release.py), driver_node, the
per-call timeouts (timeout_reset, timeout_perception, timeout_plan, timeout_execute, timeout_skill, timeout_state),
and timeout_recover (before an attempt, how long a server that has gone is waited for: a node restarting).
"""
from __future__ import annotations

import os
import sys
import threading
import traceback
from pathlib import Path

from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node

from skillgen_interfaces.action import Generate
from skillgen_interfaces.msg import FailureCount
from skillgen_interfaces.srv import PlanToPose, Recorder, RunAttempt
from skillgen_ros.core.errors import InvalidInputError, ParameterError, SkillGenError
from skillgen_ros.core.generation.profile import DEFAULT_PROFILE, get_profile
from skillgen_ros.core.generation.episode import OBSERVATION_SOURCES
from skillgen_ros.core.generation.release import ReleaseConfig
from skillgen_ros.core.generation.session import RunRequest, run_generation, validate_request
from skillgen_ros.core import validation as V
from skillgen_ros.core.skills.augmentation import MAX_TRANSLATION, AugmentationConfig
from skillgen_ros.core.skills.bag_demos import SourceDemoCache, expand_bag_paths
from skillgen_ros.core.tasks import TASK_NAMES, get_task
from skillgen_ros.core.tasks.spec import MAX_SEED
from skillgen_ros.nodes import datagen_pool
from skillgen_ros.nodes.graph_env import RosGraphEnv
from skillgen_ros.nodes.runtime import run_node

MAX_ATTEMPTS = 1_000_000  # per goal; a larger count is a typo, not a run
TIMEOUTS = {"reset": 30.0, "perception": 20.0, "plan": 10.0, "execute": 60.0, "skill": 120.0, "state": 10.0,
            "recover": 120.0}  # recover: before an attempt, how long a gone server (a node restarting) is waited for
# release.* parameters: `moves` switches unjam/follow/clear off; the rest are ReleaseConfig's fields
_RELEASE_PARAMS = {"moves": True, **{f: getattr(ReleaseConfig(), f) for f in ReleaseConfig.__dataclass_fields__}}


class DatagenNode(Node):
    def __init__(self):
        super().__init__("datagen")
        self.declare_parameter("demos_dir", "bags")
        self.declare_parameter("output_root", "out")
        self.declare_parameter("writable_roots", [""])
        self.declare_parameter("collision_source", "scene")
        self.declare_parameter("action_noise", 0.05)
        self.declare_parameter("profile", DEFAULT_PROFILE)
        self.declare_parameter("observation_source", "ground_truth")
        self.declare_parameter("write_report", True)
        for k, v in _RELEASE_PARAMS.items():
            self.declare_parameter(f"release.{k}", v)
        self.declare_parameter("driver_node", "sim_driver")
        for k, v in TIMEOUTS.items():
            self.declare_parameter(f"timeout_{k}", v)
        datagen_pool.declare(self)
        src = str(self.get_parameter("collision_source").value)
        if src not in ("point_cloud", "scene"):
            raise ParameterError(f"collision_source must be point_cloud or scene, got {src!r}")
        self._observation_source = str(self.get_parameter("observation_source").value)
        if self._observation_source not in OBSERVATION_SOURCES:
            raise ParameterError(f"observation_source must be one of {OBSERVATION_SOURCES}, "
                                 f"got {self._observation_source!r}")
        self._release = self._release_config()
        try:
            self._profile = get_profile(str(self.get_parameter("profile").value)).name
        except InvalidInputError as e:
            raise ParameterError(f"profile: {e}") from None
        try:
            timeouts = {k: V.finite(f"timeout_{k}", self.get_parameter(f"timeout_{k}").value, 0.0, 86_400.0,
                                    lo_open=True) for k in TIMEOUTS}
            V.finite("action_noise", self.get_parameter("action_noise").value, 0.0, 1.0)
        except InvalidInputError as e:
            raise ParameterError(str(e.args[0])) from None
        self._writable = [str(self.get_parameter("output_root").value),
                          *(r for r in self.get_parameter("writable_roots").value if r)]
        self.env = RosGraphEnv(self, timeouts, demos_dir="",
                               collision_source=PlanToPose.Request.SOURCE_POINT_CLOUD if src == "point_cloud"
                               else PlanToPose.Request.SOURCE_SCENE,
                               driver_node=str(self.get_parameter("driver_node").value),
                               observation_source=self._observation_source)
        self._busy = threading.Lock()
        self._demo_cache = SourceDemoCache()  # goals over the same bags parse them once
        cb = ReentrantCallbackGroup()
        self.rec_start = self.create_client(Recorder, "recorder/start", callback_group=cb)
        self.rec_stop = self.create_client(Recorder, "recorder/stop", callback_group=cb)
        self.rec_pause = self.create_client(Recorder, "recorder/pause", callback_group=cb)
        self.rec_resume = self.create_client(Recorder, "recorder/resume", callback_group=cb)
        self.server = ActionServer(self, Generate, "generate", self._execute, goal_callback=self._on_goal,
                                   cancel_callback=lambda _g: CancelResponse.ACCEPT,
                                   callback_group=MutuallyExclusiveCallbackGroup())
        self.create_service(RunAttempt, "run_attempt", self._run_attempt, callback_group=MutuallyExclusiveCallbackGroup())
        self.get_logger().info("datagen ready: action 'generate', service 'run_attempt'")

    def _release_config(self) -> ReleaseConfig:
        """The `release.*` parameters as a ReleaseConfig; a bad value is INVALID_PARAMETER at start-up."""
        v = {k: self.get_parameter(f"release.{k}").value for k in _RELEASE_PARAMS}  # typed by their defaults
        moves = v.pop("moves")
        try:
            cfg = ReleaseConfig(**v)
        except InvalidInputError as e:
            raise ParameterError(f"release.*: {e}") from None
        return cfg if moves else cfg.without_moves()

    # -- request handling
    def _request(self, g) -> RunRequest:
        """The goal (or RunAttempt request) as a RunRequest, every field checked first (reason codes)."""
        for label in ("task", "variant", "method", "selection", "profile"):
            V.name(label, getattr(g, label, ""), allow_empty=True)
        attempts = int(getattr(g, "attempts", 1))
        if attempts > MAX_ATTEMPTS:
            raise InvalidInputError(f"attempts must be <= {MAX_ATTEMPTS}, got {attempts}", reason="INVALID_ATTEMPTS")
        if int(g.seed) > MAX_SEED:
            raise InvalidInputError(f"seed must be in [0, {MAX_SEED}], got {g.seed}", reason="INVALID_SEED")
        if int(getattr(g, "video_attempts", -1)) < -1:
            raise InvalidInputError(f"video_attempts must be -1 (default), 0 or more, got {g.video_attempts}",
                                    reason="INVALID_PARAMETER")
        default = AugmentationConfig()
        out = g.output_dir or os.path.join(str(self.get_parameter("output_root").value),
                                           f"{g.task}_{g.variant}_{g.method}_seed{g.seed}")
        V.writable_path("output_dir", out, self._writable)
        if g.source_demos and len(g.source_demos) > V.MAX_PATH:
            raise InvalidInputError("source_demos is longer than a path can be", reason="INVALID_PATH")
        return RunRequest(task=g.task, variant=g.variant or "D0", method=g.method or "skillgen",
                          attempts=attempts, target_successes=int(getattr(g, "target_successes", 0)),
                          seed=int(g.seed), first_index=int(getattr(g, "first_index", getattr(g, "index", 0))),
                          augment=bool(g.augment),
                          # negative = the default (V.USE_DEFAULT, documented in Generate.action); 0 is 0
                          augment_translation=V.or_default("augment_translation", g.augment_translation,
                                                           default.translation, MAX_TRANSLATION),
                          augment_rotation_deg=V.or_default("augment_rotation_deg", g.augment_rotation_deg,
                                                            default.rotation_deg, 180.0),
                          action_noise=float(self.get_parameter("action_noise").value),
                          release=self._release, observation_source=self._observation_source,
                          profile=getattr(g, "profile", "") or self._profile,
                          selection=g.selection or "random", output_dir=out, source_demos=g.source_demos,
                          **_video_attempts(g), **_initiation_candidates(g))

    def _demos(self, req: RunRequest):
        d = req.source_demos or str(Path(str(self.get_parameter("demos_dir").value)) / req.task)
        paths = expand_bag_paths([d])
        if not paths:
            raise SkillGenError(f"no source demo bags under {d}", reason="NO_SOURCE_DEMOS")
        self.env.demos_dir = d
        return self._demo_cache.load(paths, get_task(req.task))

    def _on_goal(self, goal):
        """Busy: reject. An empty task is a readiness probe (skillgen_ros/answered.py): reject, run
        nothing. A rejection carries no reason over the action protocol, so the log says which."""
        if not goal.task:
            self.get_logger().info("generate goal with an empty task rejected (clients probe readiness this way; "
                                   "name a task to run one)")
            return GoalResponse.REJECT
        if self._busy.locked():
            self.get_logger().warning("generate goal rejected: a generation run is in progress (BUSY)")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _execute(self, goal_handle):
        with self._busy:
            return self._generate(goal_handle)

    def _generate(self, goal_handle):
        g = goal_handle.request
        res = Generate.Result()
        try:
            req = self._request(g)
            distributed = datagen_pool.is_distributed(g)
            validate_request(req, TASK_NAMES, check_output=not getattr(g, "resume", False))
            demos = self._demos(req)
            if distributed:  # Ray workers run the attempts: this node's graph is not needed
                datagen_pool.check_goal(self, g)
            else:
                missing = self.env.wait_ready(float(self.get_parameter("timeout_state").value) * 3)
                if missing:
                    raise SkillGenError(f"not available: {', '.join(missing)}", reason="GRAPH_NOT_READY")
                self.env.load_demos(req.task)  # outside the attempts' time, and a clear early error
        except SkillGenError as e:
            res.accepted, res.reason, res.message = False, e.reason, str(e.args[0])
            # the client gets the reason in the result and reports it; an ERROR here would show twice on
            # `skillgen generate`'s terminal (node warnings and errors reach it, cli/node_logs.py)
            self.get_logger().info(f"generate rejected: {e}")
            goal_handle.abort()
            return res
        except Exception as e:  # noqa: BLE001 -- a bug must answer with a reason, not kill the goal
            res.accepted, res.reason, res.message = False, "INTERNAL_ERROR", f"{type(e).__name__}: {e}"
            self.get_logger().error(f"generate failed before the run: {traceback.format_exc()}")
            goal_handle.abort()
            return res
        res.accepted = True
        bag = self._start_bag(req) if g.record_bag and not distributed else ""

        def progress(p):
            fb = Generate.Feedback(attempts=p.attempts, successes=p.successes, success_rate=p.rate,
                                   eta_seconds=p.eta_seconds, last_reason=p.last_reason)
            goal_handle.publish_feedback(fb)

        def stop():
            return "CANCELED" if goal_handle.is_cancel_requested else ""

        window = (int(g.record_first), int(g.record_first) + int(g.record_count)) if g.record_count else None

        def before_attempt(k: int) -> None:  # record only the chosen range of attempts; say which attempt runs
            if bag and window:  # first: published while the recorder is paused, the index would not be in the bag
                self._recorder_call(self.rec_resume if window[0] <= k < window[1] else self.rec_pause)
            self.env.state.attempt(req.first_index + k)

        try:
            if distributed:
                run = datagen_pool.run_goal(self, goal_handle, req, self.env.demos_dir)
            else:
                run = run_generation(self.env, demos, get_task(req.task), req, on_progress=progress,
                                     should_stop=stop, before_attempt=before_attempt,
                                     write_report=bool(self.get_parameter("write_report").value))
            res.reason = run.stopped_early or "OK"
            res.message = f"{run.successes}/{run.attempts} attempts succeeded"
        except SkillGenError as e:  # a request-level failure mid-run: partial dataset stays valid
            run = None
            res.reason, res.message = e.reason, f"run ended early: {e.args[0]}"
            self.get_logger().error(res.message)
        except Exception as e:  # noqa: BLE001 -- a bug mid-run: the written demos stay, the goal answers
            run = None
            res.reason, res.message = "INTERNAL_ERROR", f"run ended early: {type(e).__name__}: {e}"
            self.get_logger().error(f"generate failed mid-run: {traceback.format_exc()}")
        finally:
            if bag:
                self._stop_bag()
        if run is not None:
            res.attempts, res.successes = run.attempts, run.successes
            res.failures = [FailureCount(reason=k, count=v) for k, v in sorted(run.failures.items()) if v]
            res.dataset_path, res.failed_path, res.report_path = run.dataset_path, run.failed_path, run.report_path
        res.bag_path = bag
        if res.reason == "CANCELED":
            goal_handle.canceled()
        elif res.reason == "OK":
            goal_handle.succeed()
        else:
            goal_handle.abort()
        return res

    def _run_attempt(self, request, response):
        if not self._busy.acquire(blocking=False):
            response.accepted, response.reason, response.message = False, "BUSY", "a generation run is in progress"
            return response
        try:
            req = self._request(request)
            req = RunRequest(**{**req.__dict__, "attempts": 1, "first_index": int(request.index)})
            validate_request(req, TASK_NAMES)
            missing = self.env.wait_ready(5.0)  # as a call would wait for its server (graph_env._call)
            if missing:  # a graph without these cannot run an attempt: the request is refused, as generate's is
                raise SkillGenError(f"not available: {', '.join(missing)}", reason="GRAPH_NOT_READY")
            run = run_generation(self.env, self._demos(req), get_task(req.task), req, write_report=False)
            r = run.results[0]
            response.accepted, response.success = True, r.success
            response.reason, response.message, response.seconds = r.reason.value, r.message, r.timings.get("total", 0.0)
        except SkillGenError as e:
            response.accepted, response.reason, response.message = False, e.reason, str(e.args[0])
        except Exception as e:  # noqa: BLE001 -- answer with a reason, keep serving
            self.get_logger().error(f"run_attempt failed: {traceback.format_exc()}")
            response.accepted, response.reason, response.message = False, "INTERNAL_ERROR", f"{type(e).__name__}: {e}"
        finally:
            self._busy.release()
        return response

    # -- optional session recording through the recorder node
    def _start_bag(self, req: RunRequest) -> str:
        path = os.path.join(req.output_dir, "bag")
        if not self.rec_start.wait_for_service(timeout_sec=5.0):
            self.get_logger().warning("recorder/start not available; not recording this run")
            return ""
        r = self._recorder_call(self.rec_start, 10.0, Recorder.Request(output=path))
        if r is None or not r.success:
            self.get_logger().warning(f"recorder did not start: {getattr(r, 'message', 'no answer')}")
            return ""
        return r.bag_path or path

    def _stop_bag(self) -> None:
        self._recorder_call(self.rec_stop, 15.0)

    def _recorder_call(self, client, timeout: float = 5.0, request: Recorder.Request | None = None):
        ev = threading.Event()
        fut = client.call_async(request or Recorder.Request())
        fut.add_done_callback(lambda _f: ev.set())
        ev.wait(timeout)
        return fut.result() if fut.done() else None


def _video_attempts(g) -> dict:
    """RunRequest's video_attempts from a goal's (-1 or absent: keep RunRequest's default)."""
    n = int(getattr(g, "video_attempts", -1))
    return {"video_attempts": n} if n >= 0 else {}


def _initiation_candidates(g) -> dict:
    """RunRequest's initiation_candidates from a goal's (0 or absent: keep the default; < 0 is
    passed on so that validation rejects it with a reason)."""
    n = int(getattr(g, "initiation_candidates", 0))
    return {"initiation_candidates": n} if n != 0 else {}


def main(args=None) -> int:
    return run_node(DatagenNode, args)


if __name__ == "__main__":
    sys.exit(main())

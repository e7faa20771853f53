"""GenerationEnv over the ROS graph: the datagen node's view of driver, perception, planner, replay.

Algorithm 1 (core/generation/attempt.py) calls these methods; each maps to one interface:
reset -> `reset_scene`, estimate_poses -> `estimate_poses`, plan_and_execute -> `plan_to_pose`
(execute=true: the planner runs the trajectory on the driver), replay_skill -> the `replay_skill`
action, task_success -> `task_success`. Before estimating poses in a state the robot has moved to,
it asks the driver for fresh camera frames (`capture_cameras`) and has perception use a cloud no
older than them, as SimGenerationEnv renders at that moment; a reset's own frames serve the first
estimate. The run's videos are re-rendered from the recorded arrays after the run (core/dataset/render.py).
Each call also says on `run/{attempt,skill,stage}` where the attempt is (run_state.py), for Foxglove.
Observations come from `joint_states` (FK through pinocchio) and `ee_wrench`, read on demand
(nodes/latest.py); the sim's true poses and joint values come from the driver's `state_history` by
stamp, never from a topic reader in the control loop (docs/architecture.md: performance notes,
and "Changes from the starting design").
Every call has a timeout; a node that does not answer becomes a failure with a reason
(PERCEPTION_FAILED, PLAN_FAILED, SKILL_FAILED, TIMEOUT) instead of a hang, and the run goes on:
before each attempt a server seen before that has gone (a node killed and being respawned) is
waited for up to timeout_recover s (issue 19, chaos); graph_calls.py holds that plumbing.
"""
from __future__ import annotations

import time

import numpy as np
from skillgen_ros.action_client import SafeActionClient as ActionClient
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from skillgen_interfaces.action import ReplaySkill
from skillgen_interfaces.msg import OscTarget, SceneObject
from skillgen_interfaces.srv import (CaptureCameras, EstimatePoses, LoadDemos, PlanToPose, ResetScene, StateHistory,
                                     TaskSuccess)
from skillgen_ros.answered import detached, first_answer
from skillgen_ros.core.errors import SkillGenError
from skillgen_ros.core.generation.episode import Observation
from skillgen_ros.core.generation.grasp import (LookBeliefs, GraspTracker, beliefs_along, carriable,
                                               unaccounted)
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.planning.kinematics import PandaKinematics
from skillgen_ros.core.tasks.suite import get_task
from skillgen_ros.nodes import convert
from skillgen_ros.nodes.graph_calls import GraphCallError, GraphCalls
from skillgen_ros.nodes.latest import LatestMessage, wait_future
from skillgen_ros.nodes.robot_state import NewestRobotState
from skillgen_ros.nodes.run_state import RunState
from skillgen_ros.nodes.state_history import DriverHistory, ns


class RosGraphEnv(GraphCalls):
    """Implements attempt.GenerationEnv (+ the optional replay_skill hook) with ROS clients on `node`."""

    def __init__(self, node: Node, timeouts: dict, demos_dir: str = "", action_noise: float = 0.05,
                 collision_source: int = PlanToPose.Request.SOURCE_POINT_CLOUD, control_hz: float = 20.0,
                 driver_node: str = "sim_driver",
                 observation_source: str = "ground_truth"):
        self.node = node
        self.t = dict(timeouts)
        self.demos_dir = demos_dir
        self.collision_source = collision_source
        self.dt = 1.0 / control_hz
        self.observation_source = observation_source  # "estimate": skill steps carry the belief (beliefs_along)
        group = ReentrantCallbackGroup()
        self.reset_cli = node.create_client(ResetScene, "reset_scene", callback_group=group)
        self.success_cli = node.create_client(TaskSuccess, "task_success", callback_group=group)
        self.estimate_cli = node.create_client(EstimatePoses, "estimate_poses", callback_group=group)
        self.plan_cli = node.create_client(PlanToPose, "plan_to_pose", callback_group=group)
        self.replay_ac = ActionClient(node, ReplaySkill, "replay_skill", callback_group=group)
        self.capture_cli = node.create_client(CaptureCameras, "capture_cameras", callback_group=group)
        self.load_demos_cli = node.create_client(LoadDemos, "skill_replay/load_demos", callback_group=group)
        self.history = DriverHistory(node.create_client(StateHistory, "state_history", callback_group=group),
                                     lambda cli, req: self._call(cli, req, self.t["state"], "state_history", "TIMEOUT"))
        self.driver_node = driver_node
        self.state = RunState(node)
        self._next_skill = 0
        self.osc_pub = node.create_publisher(OscTarget, "osc_target", 10)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.task_pub = node.create_publisher(String, "perception/set_task", latched)
        self.robot = NewestRobotState()  # an older joint_states does not replace a newer state_history period
        # best effort, as the driver reads osc_target (driver_base.COMMANDS): a lost state costs one resend
        self._joints = LatestMessage(node, JointState, "joint_states",
                                     QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
        self._wrench = LatestMessage(node, convert.WrenchStamped, "ee_wrench")
        self.kin = PandaKinematics()
        self.task, self._task_sent = "", ""
        self.scene_objects = []
        self._cloud_floor = None  # perception must use a cloud stamped at or after this
        self._scene_stamp = None  # the reset state's stamp
        self._moved = False  # the robot moved since _cloud_floor's frames were taken
        # plan_to_pose seeds: (reset seed, plans since the reset), as SimGenerationEnv's planner draws
        self._plan_seed: int | None = None
        self._plans = 0
        self._estimates: dict[str, Pose] = {}
        self._beliefs: LookBeliefs | None = None   # per scene, made at its first look
        self.last_estimate: tuple[int, dict] | None = None  # (cloud stamp ns, what perception returned)
        self._skill_object: str | None = None
        self.grasps = GraspTracker()
        self._reset_ns: int | None = None  # stamp of this attempt's reset state (_check_driver)
        self._seen: set[str] = set()  # servers seen ready before an attempt (_await_graph waits for gone ones)

    # -- subscriptions
    def _take_joints(self, m) -> bool:
        return self.robot.take_joint_state(m)

    def _take_history_state(self, after_ns: int) -> None:
        """The driver's newest period from state_history. After a replayed skill the joint_states reader
        once held a period from before the skill (LatestMessage returned the previous read's message on
        every other read until 2026-12-07, nodes/latest.py): observations and the next plan's start were
        that stale state, and the trajectory dragged the arm back to it (Coffee Prep: from the opened
        drawer's handle to where the pull began, 14 of 20 graph attempts TASK_FAILED vs 6 in-process).
        The service answers from the driver's own record, whatever a reader holds."""
        h = self.history.periods(after_ns)
        if len(h["stamps"]):
            i = int(np.argmax(h["stamps"]))
            self.robot.take_period(h["q"][i], h["fingers"][i], h["stamps"][i])

    def wait_for_state(self, timeout: float, after: int = -1) -> bool:
        """Take the driver's newest joint_states (the first after the `after`-th, if given)."""
        m = self._joints.wait_newer(after, timeout) if after >= 0 else self._joints.latest(timeout)
        return self._take_joints(m)

    # -- GenerationEnv
    def reset(self, task: str, variant: str, seed: int):
        self._await_graph()
        self.state.stage("reset", -1)
        self._next_skill = 0  # Algorithm 1 takes the skills in order: the next motion leads to this one
        req = ResetScene.Request(task=task, variant=variant, seed=int(seed))
        _, count = self._joints.snapshot()  # the driver publishes the reset state before it answers
        resp = self._call(self.reset_cli, req, self.t["reset"], "reset_scene", "TIMEOUT")
        if not resp.success:
            raise SkillGenError(f"reset_scene: {resp.message}", reason=resp.reason_code or "RESET_FAILED")
        self.task = task
        self._plan_seed, self._plans = int(seed), 0
        self.scene_objects = list(resp.objects)
        self._cloud_floor = resp.joint_state.header.stamp  # the reset published frames of this state
        self._scene_stamp = resp.joint_state.header.stamp  # names the scene in perception's looks
        self._reset_ns = ns(resp.joint_state.header.stamp)
        self._moved = False
        if task != self._task_sent:  # latched: perception keeps it (and builds its models once)
            self.task_pub.publish(String(data=task))
            self._task_sent = task
        self._estimates, self.last_estimate, self._beliefs = {}, None, None
        self.grasps.clear()
        self.robot.new_scene()
        if not self.wait_for_state(self.t["state"], after=count):
            raise GraphCallError("no joint_states from the driver after reset", reason="TIMEOUT")
        return resp

    def _take_wrench(self, joints) -> np.ndarray | None:
        """The driver's ee_wrench of the joint_states' period (None if it publishes none)."""
        if joints is None:
            return None
        t = joints.header.stamp
        wrench = self._wrench
        # one pull: a driver that has never published a wrench is answered at once, not after 0.1 s
        m = wrench.wait_for(lambda w: wrench.count == 0 or (w.header.stamp.sec, w.header.stamp.nanosec)
                            >= (t.sec, t.nanosec), 0.1)
        return None if m is None else convert.wrench_from_msg(m)

    def observe(self) -> Observation:
        joints = self._joints.latest()
        self._take_joints(joints)
        wrench = self._take_wrench(joints)
        q, f, stamp = self.robot.snapshot()
        ee_pose = Pose.from_matrix(self.kin.fk(q))
        return Observation(ee_pose=ee_pose, gripper=f, joint_positions=q, object_poses=self._belief(ee_pose.matrix()),
                           ee_wrench=wrench, stamp_ns=None if stamp < 0 else stamp)

    def _belief(self, T_W_E: np.ndarray) -> dict[str, Pose]:
        """Where the robot believes the objects are: the latest estimates, a held object with the hand."""
        objects = dict(self._estimates)
        held = self.grasps.holding()
        if held in objects:  # rigid attachment
            objects[held] = self.grasps.pose_now(held, T_W_E)
        return objects

    def true_object_poses(self, stamps) -> dict[int, dict[str, np.ndarray]]:
        """The sim's true object poses of the periods stamped `stamps` (ns), in one state_history call."""
        return self.history.true_object_poses(stamps)

    def true_object_joints(self, stamps) -> dict[int, dict[str, float]]:
        """Articulated objects' joint values of those periods (that call's answer again: no second call)."""
        return self.history.object_joints(stamps)

    def load_demos(self, task: str) -> None:
        """Have skill_replay load the run's source demos before the first attempt (raises with its
        reason if it cannot); a skill_replay without the service loads them on the first goal."""
        if not self.load_demos_cli.wait_for_service(timeout_sec=2.0):
            return
        resp = self._call(self.load_demos_cli, LoadDemos.Request(task=task, source_demos=self.demos_dir),
                          self.t["skill"], "skill_replay/load_demos", "SKILL_FAILED")
        if not resp.success:
            raise SkillGenError(f"skill_replay cannot load the source demos: {resp.message}",
                                reason=resp.reason_code or "SKILL_FAILED")

    def wait_ready(self, timeout: float) -> list[str]:
        """Wait for every server an attempt needs; returns the names still missing after `timeout`."""
        end = time.monotonic() + timeout
        servers = [(self.reset_cli, "reset_scene"), (self.success_cli, "task_success"),
                   (self.estimate_cli, "estimate_poses"), (self.plan_cli, "plan_to_pose")]
        missing = []
        for cli, name in servers:
            if not cli.wait_for_service(timeout_sec=max(0.1, end - time.monotonic())):
                missing.append(name)
        if not self.replay_ac.wait_for_server(timeout_sec=max(0.1, end - time.monotonic())):
            missing.append("replay_skill")
        elif first_answer(lambda: detached(self.replay_ac.send_goal_async(ReplaySkill.Goal())), wait_future,
                          max(0.1, end - time.monotonic())) is None:  # answered probe: see answered.py
            missing.append("replay_skill (discovered, not answering)")
        return missing

    def _hold_period(self) -> None:
        """One control period holding the current pose and gripper (lockstep: makes the driver
        publish again, cameras included every few periods)."""
        obs = self.observe()
        g = 1.0 if self.grasps.holding() else -1.0
        self.step(Pose.from_array(obs.ee_pose), g)

    def estimate_poses(self) -> dict[str, Pose]:
        self.state.stage("perception", self._next_skill)
        if self._moved:
            self._capture()
        # No cloud (perception's camera subscription matched after the last frame, e.g. right after
        # start-up): take new frames and retry until the perception budget is spent.
        end = time.monotonic() + self.t["perception"]
        while True:
            resp, required = self._estimate_once()
            if resp.status != EstimatePoses.Response.NO_DATA or time.monotonic() > end:
                break
            self._capture()
            time.sleep(0.05)
        return self._take_estimates(resp, required)

    def _capture(self) -> None:
        """Frames of the current state (the driver's capture_cameras); a driver without the
        service (a real camera streams anyway) gets a few hold periods instead."""
        if self.capture_cli.service_is_ready():
            resp = self._call(self.capture_cli, CaptureCameras.Request(), self.t["perception"], "capture_cameras",
                              "PERCEPTION_FAILED")
            if resp.success:
                self._cloud_floor, self._moved = resp.stamp, False
                return
        for _ in range(3):
            self._hold_period()

    def _estimate_once(self):
        # in the hand: occluded, tracked instead; in a closed container: not required yet (TaskSpec.required_ids)
        ids = get_task(self.task).required_ids([o.id for o in self.scene_objects], self._next_skill,
                                               self.grasps.holding())
        req = EstimatePoses.Request(object_ids=ids)
        if self._cloud_floor is not None:
            req.newer_than = self._cloud_floor
        if self._scene_stamp is not None:
            req.scene = self._scene_stamp  # fixture poses of an earlier scene are not this one's
        return self._call(self.estimate_cli, req, self.t["perception"], "estimate_poses", "PERCEPTION_FAILED"), ids

    def _take_estimates(self, resp, required: list[str]) -> dict[str, Pose]:
        held = self.grasps.holding()
        seen = {p.id: convert.pose_from_msg(p.pose) for p in resp.poses if p.id != held}
        # an object missed now keeps its belief; one never seen fails the estimate (grasp.unaccounted), and so
        # does a look that failed as a whole (no table, an empty cloud)
        if resp.status != EstimatePoses.Response.OK and (resp.status != EstimatePoses.Response.OBJECT_MISSING
                                                         or unaccounted(required, seen, self._estimates)):
            raise SkillGenError(f"estimate_poses: {resp.status_name}: {resp.message}", reason="PERCEPTION_FAILED")
        # the hand occludes a held object (the grasp tracker knows where it is); untouched objects and fixtures: LookBeliefs
        confidence = {p.id: p.confidence for p in resp.poses}
        self._beliefs = self._beliefs or LookBeliefs(get_task(self.task))
        self._estimates.update(self._beliefs.update(seen, confidence, self._estimates, self._next_skill))
        floor = self._cloud_floor
        self.last_estimate = (None if floor is None else ns(floor), seen)  # frames of that stamp (or newer)
        return dict(self._estimates)

    def current_ee_pose(self) -> Pose:
        return self.observe().ee_pose

    def current_q(self) -> np.ndarray:
        self._take_joints(self._joints.latest())
        return self.robot.snapshot()[0]

    def _scene_for_planner(self):
        """The reset's scene objects placed at the latest estimated poses (the planner's boxes locate
        the attached object and the allowed contacts; obstacles come from the cloud)."""
        out = []
        ee = self.observe().ee_matrix()
        held = self.grasps.holding()
        hidden = get_task(self.task).hidden_at(self._next_skill)  # not seen yet: no box at its true reset pose
        for o in self.scene_objects:
            m = SceneObject(id=o.id, type=o.type, mesh_uri=o.mesh_uri, half_extents=list(o.half_extents),
                            is_fixture=o.is_fixture)
            est = self.grasps.pose_now(o.id, ee) if o.id == held else self._estimates.get(o.id)
            if est is not None:
                m.has_pose, m.pose = True, convert.pose_to_msg(est)
            elif o.has_pose and self.collision_source == PlanToPose.Request.SOURCE_SCENE and o.id not in hidden:
                m.has_pose, m.pose = True, o.pose
            out.append(m)
        return out

    def set_skill_object(self, object_id: str | None) -> None:
        self._skill_object = object_id

    def set_next_skill(self, skill_index: int) -> None:
        """The attempt's next skill (run_state's stage, and which objects perception requires)."""
        self._next_skill = int(skill_index)

    _planner_extras = True

    def set_planner_extras(self, on: bool) -> None:
        """The attempt's profile (core/generation/profile.py), sent as PlanToPose.extras."""
        self._planner_extras = bool(on)

    def plan_and_execute(self, target: Pose, mode: str, attached: str | None):
        self.state.stage("motion", self._next_skill)
        req = PlanToPose.Request()
        req.target = convert.pose_stamped(target, "world", self.node.get_clock().now().to_msg())
        req.mode = PlanToPose.Request.TRANSFER if mode == "transfer" else PlanToPose.Request.TRANSIT
        req.attached_object = attached or ""
        req.collision_source = self.collision_source
        req.timeout = float(self.t["plan"])
        req.execute = True
        self._moved = True
        self._take_joints(self._joints.latest())
        q, _, start_ns = self.robot.snapshot()
        req.start_positions = [float(v) for v in q]
        req.objects = self._scene_for_planner()
        req.manipulated_object = self._skill_object or ""
        req.extras = self._planner_extras
        if self._plan_seed is not None:
            req.seeded, req.seed, req.plan_index = True, self._plan_seed, self._plans
        self._plans += 1
        resp = self._call(self.plan_cli, req, self.t["plan"] + self.t["execute"], "plan_to_pose", "PLAN_FAILED",
                          idempotent=False)  # it moves the robot
        status = resp.status_name or str(resp.status)
        if resp.status == PlanToPose.Response.EXECUTION_FAILED:
            self._check_driver()  # a driver gone mid-trajectory is not a collision
        executed = resp.status in (PlanToPose.Response.SUCCESS, PlanToPose.Response.EXECUTION_FAILED)
        if executed and start_ns >= 0 and self.history.ready():
            obs = self._executed_periods(start_ns)  # measured, as the in-process env records
        elif resp.status == PlanToPose.Response.SUCCESS:
            obs = self._planned_samples(resp.trajectory)
        else:
            return status, []
        if obs:
            obs[-1] = self.observe()  # the state where execution ended, with its wrench
        return status, obs

    def _executed_periods(self, after_ns: int) -> list[Observation]:
        """One observation per trajectory period the driver ran after `after_ns` (state_history)."""
        return [Observation(ee_pose=Pose.from_matrix(T := self.kin.fk(q)), gripper=f, joint_positions=q,
                            object_poses=self._belief(T), stamp_ns=t, true_object_poses=truth, object_joints=j)
                for t, q, f, truth, j in self.history.trajectory_periods(after_ns)]

    def _planned_samples(self, trajectory) -> list[Observation]:
        """A driver without state_history: the planned trajectory at the control rate (commanded)."""
        _, times, pos, _ = convert.trajectory_from_msg(trajectory)
        fingers = self.observe().gripper
        out = []
        for t in np.arange(self.dt, times[-1] + 1e-9, self.dt):
            q = np.array([np.interp(t, times, pos[:, j]) for j in range(pos.shape[1])])
            T = self.kin.fk(q)
            out.append(Observation(ee_pose=Pose.from_matrix(T), gripper=fingers, joint_positions=q,
                                   object_poses=self._belief(T)))
        return out

    def replay_skill(self, skill_index: int, demo_index: int, T_W_O: np.ndarray, sigma: float,
                     recovery: bool, seed: int):
        """The skill_replay action: returns (steps, ok, reason, message); steps as arrays."""
        self.state.stage("skill", skill_index)
        self._next_skill = int(skill_index) + 1
        if not self.replay_ac.wait_for_server(timeout_sec=5.0):
            raise GraphCallError("replay_skill action server is not available", reason="SKILL_FAILED")
        goal = ReplaySkill.Goal(skill_index=int(skill_index), source_demo=int(demo_index),
                                source_demos=self.demos_dir, task=self.task, selection="random",
                                action_noise=float(sigma), recovery=bool(recovery), seed=int(seed))
        goal.object_pose = convert.pose_to_msg(Pose.from_matrix(T_W_O))
        self._moved = True
        result = self._wait_action(self.replay_ac.send_goal_async(goal), self.t["skill"])
        r = result.result
        steps, n = replay_steps(r), int(r.steps)
        if n and len(r.stamps) == n and self.history.ready():
            steps.update(self.history.skill_periods([ns(t) for t in r.stamps]))
            self._take_history_state(ns(r.stamps[-1]) - 1)
        if self.observation_source == "estimate":  # the belief is what such a dataset records
            steps["object_poses"] = self._beliefs_along(steps)
        # after a skill: a hand closed on the skill's object holds it rigidly; one let go stays where left
        self._estimates.update(self.grasps.after_skill(steps["actions_abs"][:, 7], steps["ee_poses"],
                                                       carriable(self.task, self._skill_object), self._estimates))
        return steps, bool(r.success), r.reason, r.message

    def _beliefs_along(self, steps) -> list[dict]:
        """The belief before each skill step (grasp.beliefs_along), as SimGenerationEnv tracks it."""
        held = self.grasps.holding()
        return beliefs_along(self._estimates, None if held is None else (held, self.grasps.object_in_ee(held)),
                             carriable(self.task, self._skill_object),
                             [Pose.from_array(e).matrix() for e in steps["ee_poses"]],
                             steps["actions_abs"][:, 7])

    def step(self, target: Pose, gripper: float) -> Observation:
        """One OSC command (MimicGen's interpolation steps); waits for the driver's next joint_states."""
        snap, count = self._joints.snapshot()
        msg = OscTarget(pose=convert.pose_to_msg(target), gripper=float(gripper))
        msg.header.frame_id, msg.header.stamp = "world", self.node.get_clock().now().to_msg()
        self._moved = True
        if not self._await_step(msg, snap, count):
            raise GraphCallError("driver did not step after an osc_target", reason="TIMEOUT")
        return self.observe()

    def task_success(self) -> bool:
        self._check_driver()
        self.state.stage("success", -1)
        resp = self._call(self.success_cli, TaskSuccess.Request(), self.t["reset"], "task_success", "TIMEOUT")
        return bool(resp.success)

    def collided(self) -> bool:
        return False  # the planner's EXECUTION_FAILED status carries execution problems


def replay_steps(r: ReplaySkill.Result) -> dict[str, np.ndarray]:
    """A replay_skill result's flat arrays as (steps, ...) arrays."""
    n = int(r.steps)
    return {"actions": np.asarray(r.actions, float).reshape(n, 7),
            "actions_abs": np.asarray(r.actions_abs, float).reshape(n, 8),
            "ee_poses": np.asarray(r.ee_poses, float).reshape(n, 7),
            "joint_positions": np.asarray(r.joint_positions, float).reshape(n, 7),
            "gripper_widths": np.asarray(r.gripper_widths, float).reshape(n),
            "recovery": np.asarray(r.recovery_steps, bool).reshape(n)}

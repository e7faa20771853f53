"""The robot-driver ROS interface shared by sim_driver and mock_driver.

Both drivers expose the same topics, services and actions (docs/architecture.md); only the world
behind them differs (core.sim.SimWorld: pybullet physics; core.sim.mock.MockWorld: kinematic).
Timing modes (parameter timing_mode):
- realtime: a wall-clock timer advances one control period per 1/control_hz, tracking the latest
  osc_target (or the active trajectory); stamps are wall time.
- lockstep: the world advances one control period per received osc_target, or after
  lockstep_timeout_s of wall time without one (holding the last command). While an
  execute_trajectory / gripper_command goal runs, the action advances the world itself. /clock
  carries the world time, and every stamp is world time. An osc_target with the header stamp of
  the last one applied (a client's resend, nodes/graph_calls.py) is not applied again: the
  driver publishes that period's joint_states again instead (stamp 0 is never a repeat).
Bad input never stops the driver: services answer with a reason code, actions with an error code,
and rejected osc_target messages are logged and published as "REASON: message" on driver/errors;
the robot keeps its previous command. Targets more than 0.10 m outside the workspace box are
rejected (OUT_OF_WORKSPACE), nearer ones clamped onto it (core/sim/commands.py).
Every published state also goes into a bounded ring (history_periods), answered by the
`state_history` service: the measured states of an executed trajectory, the world's object poses
(the sim's ground truth) and articulated objects' joint values (as object_joint_states names them)
per period, for a dataset's steps, without a topic reader in the loop.
"""
from __future__ import annotations

import threading
import time
from collections import deque
from typing import Callable

import numpy as np
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.action import ActionServer, CancelResponse
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Header, String
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped

from skillgen_interfaces.action import ExecuteTrajectory, Gripper
from skillgen_interfaces.msg import GripperState, ObjectPose, ObjectPoseArray, OscTarget, SceneObject
from skillgen_interfaces.srv import CaptureCameras, ResetScene, StateHistory, TaskSuccess
from skillgen_ros.core import validation as V
from skillgen_ros.core.errors import ParameterError, SkillGenError
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.robot import ARM_JOINTS, FINGER_JOINTS
from skillgen_ros.core.sim.commands import validate_gripper, validate_osc_target
from skillgen_ros.nodes import convert
from skillgen_ros.nodes.driver_actions import DriverActions
from skillgen_ros.nodes.driver_cameras import DriverCameras
from skillgen_ros.nodes.driver_joints import ObjectJointStates
from skillgen_ros.nodes.feedback import RESULT_TIMEOUT_S

PARAMS = {  # name: (default, description)
    "timing_mode": ("lockstep", "realtime (wall-clock timer) or lockstep (one period per osc_target / timeout)"),
    "lockstep_timeout_s": (0.5, "lockstep: wall seconds without osc_target after which one period advances anyway"),
    "control_hz": (20.0, "control period rate (OSC targets, joint_states, ee_pose)"),
    "frame_id": ("world", "frame of every pose (the robot base is at its origin)"),
    "cameras": (["front", "wrist"], "cameras to render and publish"),
    "camera_hz": (10.0, "periodic camera frames per (sim) second, rounded to a divisor of control_hz; 0 = none "
                        "(frames still come on reset_scene and capture_cameras); may be changed at run time"),
    "front_width": (0, "front camera width (px); 0 x 0: the task's size (TaskSpec.camera_size: 128x128, "
                       "Threading 480x360)"),
    "front_height": (0, "front camera height (px); 0 with front_width 0"),
    "front_fov_deg": (55.0, "front camera vertical field of view"),
    "wrist_width": (96, "wrist camera width (px)"), "wrist_height": (96, "wrist camera height (px)"),
    "wrist_fov_deg": (70.0, "wrist camera vertical field of view"),
    "depth_noise_base": (0.0, "depth noise sigma = base + quadratic * z^2 (m)"),
    "depth_noise_quadratic": (0.0, "depth noise quadratic coefficient (1/m)"),
    "depth_dropout": (0.0, "probability a depth pixel is missing"),
    "publish_points": (True, "publish camera/<name>/points (PointCloud2, world frame)"),
    "feedback_hz": (20.0, "action feedback at most this often (wall clock; joint_trajectory_controller's "
                          "action_monitor_rate): every period in realtime, not a flood in lockstep"),
    "initial_task": ("", "task to reset to at startup ('' = empty scene until reset_scene)"),
    "initial_variant": ("D0", "variant for initial_task"),
    "initial_seed": (0, "seed for initial_task"),
    "history_periods": (12000, "control periods kept for state_history (12000: 10 min at 20 Hz)"),
}
RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
# osc_target is read best effort (it matches reliable publishers too): a lockstep client resends a
# target it got no state for (graph_calls.RESEND_AFTER_S), and a reliable reader holds every later
# sample back until a lost one is repaired, which stalled a deploy graph 10 s (docs/hsp.md).
COMMANDS = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class DriverNode(DriverActions, Node):
    """ROS shell over a world object (SimWorld or MockWorld); see the module docstring."""

    def __init__(self, name: str, make_world: Callable[[Callable], object], extra_params: dict | None = None):
        super().__init__(name)
        for pname, (default, desc) in {**PARAMS, **(extra_params or {})}.items():
            self.declare_parameter(pname, default, ParameterDescriptor(description=desc))
        self.mode = self.param("timing_mode")
        if self.mode not in ("realtime", "lockstep"):
            raise ParameterError(f"timing_mode must be realtime or lockstep, got {self.mode!r}")
        # Lockstep: one thread. Every callback is short or runs the world at full speed (an action
        # in lockstep never sleeps), and the osc_target -> step -> publish round trip is the graph's
        # hot path, which a thread-pool handoff per message slows by about a third.
        # Real time: actions pace themselves with sleeps, so other callbacks need other threads.
        self.executor_kind = "single" if self.mode == "lockstep" else "multi"
        try:  # finite and in range (NaN and inf fail these checks)
            self.hz = V.finite("control_hz", self.param("control_hz"), 0.0, 10_000.0, lo_open=True)
            V.finite("lockstep_timeout_s", self.param("lockstep_timeout_s"), 0.0, 3600.0, lo_open=True)
            V.finite("feedback_hz", self.param("feedback_hz"), 0.0, 10_000.0)  # 0 = every period
            V.finite("camera_hz", self.param("camera_hz"), 0.0, 10_000.0)
            for k in ("depth_noise_base", "depth_noise_quadratic"):
                V.finite(k, self.param(k), 0.0, 1.0)
            V.finite("depth_dropout", self.param("depth_dropout"), 0.0, 1.0)
        except SkillGenError as e:
            raise ParameterError(str(e.args[0])) from None
        self.frame = self.param("frame_id")
        self.world = make_world(self.param)
        self.lock = threading.RLock()
        self.period = 0
        self.busy = False           # an action is driving the world (lockstep) or a trajectory runs
        self._pending: tuple[Pose, float] | None = None
        self._last_step_wall = time.monotonic()
        self._last_target = (0, 0)  # header stamp of the last osc_target applied (lockstep resends)
        self._last_js = None  # the last joint_states message published (answers a resend)
        self._types: dict[str, str] = {}
        self._clock_base = 0.0  # lockstep: sim seconds of earlier scenes, so /clock never goes back
        if int(self.param("history_periods")) < 1:
            raise ParameterError("history_periods must be >= 1")
        # (stamp ns, arm + finger positions (9,), object ids, object poses (K, 7), kind, joint names,
        # joint values (J,)) per published state
        self._history: deque = deque(maxlen=int(self.param("history_periods")))

        cb = ReentrantCallbackGroup()
        # publishers without default QoS-event handlers: each handler joins every executor wait set,
        # and with ~20 publishers that rebuild dominated the lockstep round trip (bench/sim_driver)
        ev = PublisherEventCallbacks(use_default_callbacks=False)

        def pub(typ, topic, qos):
            return self.create_publisher(typ, topic, qos, event_callbacks=ev)
        self.pub_js = pub(convert.JointState, "joint_states", RELIABLE)
        self.pub_ee = pub(PoseStamped, "ee_pose", RELIABLE)
        self.pub_grip = pub(GripperState, "gripper_state", RELIABLE)
        self.pub_wrench = pub(convert.WrenchStamped, "ee_wrench", RELIABLE)
        self.pub_gt = pub(ObjectPoseArray, "sim/ground_truth/object_poses", LATCHED)
        self.obj_joints = ObjectJointStates(pub, self.frame)  # object_joint_states (nodes/driver_joints.py)
        self.pub_err = pub(String, "driver/errors", RELIABLE)
        self.pub_clock = pub(Clock, "/clock", RELIABLE) if self.mode == "lockstep" else None
        self.cameras = DriverCameras([c for c in self.param("cameras") if c], self.frame, self.hz,
                                     self.param("camera_hz"), pub)
        self.create_subscription(OscTarget, "osc_target", self._on_target, COMMANDS,
                                 callback_group=MutuallyExclusiveCallbackGroup(),
                                 event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
        self.create_service(ResetScene, "reset_scene", self._on_reset, callback_group=cb)
        self.create_service(TaskSuccess, "task_success", self._on_success, callback_group=cb)
        self.create_service(CaptureCameras, "capture_cameras", self._on_capture, callback_group=cb)
        self.create_service(StateHistory, "state_history", self._on_history, callback_group=cb)
        self.traj_server = ActionServer(self, ExecuteTrajectory, "execute_trajectory", self._exec_traj,
                                        goal_callback=self._one_goal, cancel_callback=lambda _g: CancelResponse.ACCEPT,
                                        callback_group=cb, result_timeout=RESULT_TIMEOUT_S)
        self.grip_server = ActionServer(self, Gripper, "gripper_command", self._exec_gripper,
                                        goal_callback=self._one_goal, cancel_callback=lambda _g: CancelResponse.ACCEPT,
                                        callback_group=cb, result_timeout=RESULT_TIMEOUT_S)
        wall_period = 1.0 / self.hz if self.mode == "realtime" else min(0.05, float(self.param("lockstep_timeout_s")))
        self.create_timer(wall_period, self._on_timer, callback_group=MutuallyExclusiveCallbackGroup())
        if self.param("initial_task"):
            try:
                scene = self.world.reset(self.param("initial_task"), self.param("initial_variant"),
                                         self.param("initial_seed"))
                self._types = {o.id: o.type for o in scene.objects}
            except SkillGenError as e:
                raise ParameterError(f"initial scene: {e}")
        self._publish(cameras=True, force=True)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.get_logger().info(f"{name} up: {self.mode}, {self.hz:g} Hz, cameras {self.cameras.names}")

    def param(self, name: str):
        return self.get_parameter(name).value

    def _on_set_parameters(self, params) -> SetParametersResult:
        """camera_hz, lockstep_timeout_s, publish_points and feedback_hz apply at once (datagen
        raises camera_hz while it films an attempt); the rest shape the world or the interface
        at start-up, so changing them later is refused rather than silently ignored."""
        live = {"camera_hz", "lockstep_timeout_s", "publish_points", "feedback_hz", "use_sim_time"}
        every = None
        for p in params:  # all or nothing: check every change before applying any
            if p.name not in live:
                return SetParametersResult(successful=False, reason=f"{p.name} is read-only after start-up")
            try:
                if p.name == "camera_hz":
                    every = self.cameras.periods_per_frame(p.value)
                elif p.name in ("lockstep_timeout_s", "feedback_hz"):
                    V.finite(p.name, p.value, 0.0, 10_000.0, lo_open=p.name == "lockstep_timeout_s")
            except (SkillGenError, TypeError, ValueError) as e:
                return SetParametersResult(successful=False, reason=str(e))
        if every is not None:
            self.cameras.every = every
        return SetParametersResult(successful=True)

    # ----------------------------------------------------------------- stepping
    def _stamp(self) -> Time:
        if self.mode == "lockstep":
            ns = int(round((self._clock_base + self.world.time) * 1e9))  # t = 1.9999999996 is 2 s, not 1 s
            return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        return self.get_clock().now().to_msg()

    def _advance(self, fn, kind: int) -> None:
        """Run one control period (fn does it on the world), then publish the new state; `kind`
        (StateHistory.Response.<KIND>) says what drove it."""
        with self.lock:
            fn()
            self.period += 1
            self._last_step_wall = time.monotonic()
            self._publish(cameras=self.cameras.due(self.period), kind=kind)

    def _on_target(self, msg: OscTarget) -> None:
        try:
            arrays = convert.pose_arrays_from_msg(msg.pose)
            validate_osc_target(*arrays)  # rejects here; the world validates the message's own values again, so
            target = Pose(*arrays)  # they are normalized once, bit for bit as an in-process world.step does
            grip = validate_gripper(msg.gripper)
        except SkillGenError as e:
            return self._report(e)
        if self.busy:
            return self._report(SkillGenError("osc_target ignored while an action drives the robot", "BUSY"))
        if self.mode == "lockstep":
            key = (msg.header.stamp.sec, msg.header.stamp.nanosec)
            if key != (0, 0) and key == self._last_target:  # a client's resend (graph_calls.RESEND_AFTER_S):
                if self._last_js is not None:  # applied once; it gets this period's state again
                    self.pub_js.publish(self._last_js)
                return
            self._last_target = key
            self._advance(lambda: self.world.step(target, grip), StateHistory.Response.OSC_TARGET)
        else:
            self._pending = (target, grip)

    def _on_timer(self) -> None:
        if self.mode == "realtime":
            if self.busy:
                return  # the running action advances the world on its own schedule
            pending, self._pending = self._pending, None
            if pending:
                self._advance(lambda: self.world.step(*pending), StateHistory.Response.OSC_TARGET)
            else:
                self._advance(lambda: self.world.idle(1), StateHistory.Response.HOLD)
        elif not self.busy and time.monotonic() - self._last_step_wall >= float(self.param("lockstep_timeout_s")):
            self._advance(lambda: self.world.idle(1), StateHistory.Response.HOLD)

    def _report(self, e: SkillGenError) -> None:
        self.get_logger().warning(str(e), throttle_duration_sec=1.0)
        self.pub_err.publish(String(data=str(e)))

    def _wait_period(self, t0: float, k: int) -> None:
        """Realtime actions keep the wall-clock schedule; lockstep ones run as fast as they can."""
        if self.mode == "realtime":
            delay = t0 + k / self.hz - time.monotonic()
            if delay > 0:
                time.sleep(delay)

    # ----------------------------------------------------------------- publishing
    def _publish(self, cameras: bool, force: bool = False, kind: int = StateHistory.Response.RESET) -> None:
        """Publish this period's state. A topic nobody subscribes to is skipped (building and
        serializing the message is most of a publish in rclpy, and no reader can tell the
        difference: none of these is latched but ground truth, which `force`, e.g. on a reset,
        always sends so the latched value is the current scene). A camera renders only when one
        of its topics has a reader."""
        w, stamp = self.world, self._stamp()
        header = Header(frame_id=self.frame, stamp=stamp)

        def wanted(*pubs) -> bool:
            return force or any(p.get_subscription_count() for p in pubs)

        q = np.concatenate([w.joint_positions(), w.finger_positions()])
        poses, joints = (w.object_poses(), w.object_joints()) if w.scene is not None else ({}, {})
        self._history.append((stamp.sec * 1_000_000_000 + stamp.nanosec, q, tuple(poses),
                              np.array([p.as_array() for p in poses.values()]).reshape(-1, 7), kind,
                              tuple(joints), np.fromiter(joints.values(), float, len(joints))))

        if self.pub_clock is not None and wanted(self.pub_clock):
            self.pub_clock.publish(Clock(clock=stamp))
        # the external wrench on the hand (a Panda's O_F_ext_hat_K); before joint_states, which
        # clients wait on, so the period's wrench is there when they look
        if wanted(self.pub_wrench):
            self.pub_wrench.publish(convert.wrench_stamped(w.ee_wrench(), self.frame, stamp))
        if wanted(self.pub_js):
            qd = np.concatenate([w.joint_velocities(), np.zeros(2)])
            self._last_js = convert.joint_state(ARM_JOINTS + FINGER_JOINTS, q, qd, stamp=stamp)
            self.pub_js.publish(self._last_js)
        if wanted(self.pub_grip):
            self.pub_grip.publish(GripperState(header=header, width=float(w.gripper_width()),
                                               command=float(w.gripper_command), grasping=bool(w.is_grasping())))
        # ee_pose last: a client closing the loop on it sees the whole period's state out before it
        if wanted(self.pub_ee):
            self.pub_ee.publish(convert.pose_stamped(w.ee_pose(), self.frame, stamp))
        if w.scene is not None and wanted(self.pub_gt):
            self.pub_gt.publish(ObjectPoseArray(header=header, objects=[
                ObjectPose(id=oid, type=self._types[oid], pose=convert.pose_to_msg(p), confidence=1.0)
                for oid, p in poses.items()]))
        self.obj_joints.publish(w, stamp, force)
        if cameras:  # only cameras with a reader, even when forced: none is latched
            self.cameras.publish(w, stamp, bool(self.param("publish_points")))

    # ----------------------------------------------------------------- services
    def _on_reset(self, req: ResetScene.Request, res: ResetScene.Response) -> ResetScene.Response:
        try:
            V.name("task", req.task, reason="UNKNOWN_TASK")
            V.name("variant", req.variant, reason="UNKNOWN_VARIANT")
            with self.lock:
                base = self._clock_base + self.world.time + 1.0 / self.hz
                scene = self.world.reset(req.task, req.variant, int(req.seed))
                self._clock_base = base  # the reset state is stamped after everything before it
                self._types = {o.id: o.type for o in scene.objects}
                self._publish(cameras=True, force=True)
                reset_stamp = self._stamp()
        except SkillGenError as e:
            res.success, res.reason_code, res.message = False, e.reason, str(e)
            self._report(e)
            return res
        except Exception as e:  # noqa: BLE001 - report, keep serving
            self.get_logger().error(f"reset_scene failed: {e!r}")
            res.success, res.reason_code, res.message = False, "INTERNAL_ERROR", repr(e)
            return res
        res.success, res.reason_code, res.message = True, "OK", f"{req.task}/{req.variant} seed {req.seed}"
        res.objects = [SceneObject(id=o.id, type=o.type, mesh_uri=o.mesh_path, half_extents=list(o.half_extents),
                                   has_pose=True, pose=convert.pose_to_msg(scene.poses[o.id]), is_fixture=o.is_fixture)
                       for o in scene.objects]
        res.joint_state = convert.joint_state(ARM_JOINTS, scene.joint_positions, stamp=reset_stamp)
        return res

    def _on_capture(self, _req: CaptureCameras.Request, res: CaptureCameras.Response) -> CaptureCameras.Response:
        if not self.cameras.names:
            res.success, res.reason_code, res.message = False, "NO_CAMERAS", "parameter cameras is empty"
            return res
        try:
            with self.lock:
                stamp = self._stamp()
                self.cameras.publish(self.world, stamp, bool(self.param("publish_points")), only_read=False)
        except Exception as e:  # noqa: BLE001 - report, keep serving
            res.success, res.reason_code, res.message = False, "INTERNAL_ERROR", repr(e)
            return res
        res.success, res.reason_code, res.stamp = True, "OK", stamp
        res.message = f"captured {', '.join(self.cameras.names)}"
        return res

    def _on_history(self, req: StateHistory.Request, res: StateHistory.Response) -> StateHistory.Response:
        after = req.after.sec * 1_000_000_000 + req.after.nanosec
        until = req.until.sec * 1_000_000_000 + req.until.nanosec or None
        with self.lock:
            if self._history and self._history[0][0] > after and len(self._history) == self._history.maxlen:
                res.reason_code, res.message = "HISTORY_EXPIRED", "periods after that stamp are no longer kept"
                return res
            rows = []
            for row in reversed(self._history):  # requests are for recent periods: walk back from the newest
                if row[0] <= after:
                    break
                if until is None or row[0] <= until:
                    rows.append(row)
        rows.reverse()
        if any(r[4] == StateHistory.Response.RESET for r in rows[1:]):
            res.reason_code, res.message = "SCENE_CHANGED", "the periods span a reset_scene"
            return res
        res.stamps = [Time(sec=t // 1_000_000_000, nanosec=t % 1_000_000_000) for t, *_ in rows]
        res.kinds = [int(r[4]) for r in rows]
        res.joint_positions = [float(v) for r in rows for v in r[1][:7]]
        res.finger_positions = [float(v) for r in rows for v in r[1][7:9]]
        res.object_ids = list(rows[0][2]) if rows else []
        res.object_poses = np.concatenate([r[3].reshape(-1) for r in rows]).tolist() if rows else []
        res.joint_names = list(rows[0][5]) if rows else []
        res.object_joints = np.concatenate([r[6] for r in rows]).tolist() if rows else []
        res.success, res.reason_code, res.message = True, "OK", f"{len(rows)} periods"
        return res

    def _on_success(self, req: TaskSuccess.Request, res: TaskSuccess.Response) -> TaskSuccess.Response:
        with self.lock:
            scene = self.world.scene
            res.task = scene.task if scene else ""
            res.success = bool(self.world.task_success()) if scene else False
            res.message = "no scene: call reset_scene first" if scene is None else "ok"
        return res

    def destroy_node(self):
        self.traj_server.destroy()
        self.grip_server.destroy()
        self.world.close()
        super().destroy_node()


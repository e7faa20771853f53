"""planner node: plan_to_pose (retreat -> transit/transfer -> approach), optional execution.

Interfaces (relative names):
- service `plan_to_pose` (skillgen_interfaces/srv/PlanToPose)
- reads the newest `joint_states` on demand when a request gives no start configuration (like
  the clouds below: in lockstep joint_states come hundreds of times a second and each would wake
  a subscribed node); the reader is made on the first such request, so a graph whose client
  always sends start_positions costs the driver no delivery per period
- reads `camera/front/points` + `camera/wrist/points` (sensor QoS) and `perception/obstacles`
  (reliable, transient local) for SOURCE_POINT_CLOUD; the perception cloud wins when present.
  They are read on demand, the newest at request time (nodes/latest.py), and decoded only then;
  the readers are made on the first point-cloud request (which waits up to 1 s for the latched
  obstacle cloud). With `cloud_hidden_space`, each organized camera cloud also becomes a depth
  view through `camera/<name>/pose` and `camera/<name>/camera_info` of the same stamp (read
  the same way), and the space hidden behind what it saw is occupied, as in-process
  (CollisionModel.set_point_cloud(views=...); docs/planning.md).
- reads the driver's `object_joint_states` (sensor_msgs/JointState, latched; nodes/driver_joints.py) on
  demand when the scene has an articulated object (a SceneObject whose `type` is one in core/tasks with
  joints, e.g. Coffee's machine): its links (the lid) are obstacles at the current joint values, as
  boxes (SOURCE_SCENE) or as points on those boxes added to the cloud (SOURCE_POINT_CLOUD: perception's
  obstacle cloud drops the recognized machine, lid included), and count as the object for allowed
  contacts. No message: the joints are at their reset values (a warning). PlanToPose is unchanged.
- publishes `planner/path_markers` (visualization_msgs/MarkerArray, latched) for Foxglove
- action client `execute_trajectory` (skillgen_interfaces/action/ExecuteTrajectory)

Scene geometry: the request carries `objects` (SceneObject[] as reset_scene returns them). A
non-empty list replaces the node's scene; an empty one reuses the latest. With SOURCE_SCENE the
boxes are the obstacles; with SOURCE_POINT_CLOUD the cloud is (an empty cloud = no obstacles;
robot points are filtered at the start configuration; the space below observed points is filled
down to the table), and the boxes only locate the attached object and the allowed contacts. The
table is always the half-space z < 0. Clouds must be in the world frame ("", "world" or
"panda_link0": the base is at the world origin).
Allowed contacts: in TRANSIT the hand may touch `manipulated_object` on the approach and, on the
retreat, the object whose box contains the start EE position (just released); in TRANSFER the
held object (`attached_object`, attached as spheres filling its box) may touch the box right
below it at the start and at the goal (or the table). Both modes add the paper's rule for the
retreat and the approach: the hand may touch any manipulated object (a scene object a task defines
as a non-fixture) and a held object anything. Bad requests are answered with a status code; the
node keeps serving.
Callbacks: the service runs in its own mutually exclusive group; subscriptions and the action
client in a reentrant group, so clouds keep updating while a request plans or executes.
"""
from __future__ import annotations

import sys
import time
import traceback

import numpy as np
from rcl_interfaces.msg import ParameterDescriptor
from skillgen_ros.action_client import SafeActionClient as ActionClient
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.qos import QoSDurabilityPolicy, QoSProfile, QoSReliabilityPolicy, qos_profile_sensor_data
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import CameraInfo, JointState, PointCloud2
from visualization_msgs.msg import MarkerArray

from skillgen_interfaces.action import ExecuteTrajectory
from skillgen_interfaces.msg import PhaseTiming
from skillgen_interfaces.srv import PlanToPose
from skillgen_ros.core.errors import InvalidInputError, ParameterError, SkillGenError
from skillgen_ros.core.geometry import validate_pose
from skillgen_ros.core.planning.articulated import (attached_from_parts, box_points, part_boxes, scene_link_boxes,
                                                    support_below)
from skillgen_ros.core.planning.collision import HIDDEN_REFINE, SHADOW_PX, AttachedObject, Box, CollisionModel
from skillgen_ros.core.planning.ik import IKSolver
from skillgen_ros.core.planning.kinematics import PandaKinematics
from skillgen_ros.core.planning.occlusion import MAX_REFINE, DepthView
from skillgen_ros.core.planning.planner import Mode, MotionPlanner, PlanStatus
from skillgen_ros.core import validation as V
from skillgen_ros.core.robot import ARM_JOINTS, Q_LOWER, Q_UPPER
from skillgen_ros.core.tasks import articulated_object, scene_object_spec
from skillgen_ros.nodes import convert
from skillgen_ros.nodes.driver_joints import ObjectJointReader
from skillgen_ros.nodes.latest import LatestMessage, wait_future
from skillgen_ros.nodes.planner_markers import path_markers
from skillgen_ros.nodes.runtime import run_node

WORLD_FRAMES = ("", "world", "panda_link0")
CAMERA_CLOUDS = ("camera/front/points", "camera/wrist/points")
LATCHED = QoSProfile(depth=1, reliability=QoSReliabilityPolicy.RELIABLE,
                     durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
PARAMS = {  # name: (default, description)
    "default_timeout": (2.0, "planning budget (s) when the request's timeout is <= 0"),
    "ik_iterations": (2000, "goal IK budget in batch iterations (about 50 ms; machine-independent)"),
    "ik_timeout": (5.0, "wall-time cap (s) on the goal IK (a safety net; the iterations bound it)"),
    "rrt_iterations": (100, "RRT-Connect budget in search iterations (machine-independent; the timeout caps it)"),
    "retreat_distance": (0.05, "retreat along the gripper's -z (m)"),
    "approach_distance": (0.05, "approach along the gripper's +z (m)"),
    "box_margin": (0.005, "safety margin against scene boxes (m)"),
    "cloud_margin": (0.01, "safety margin against point-cloud points (m)"),
    "cloud_fill_below": (True, "treat the space under observed points as occupied (heightmap)"),
    "cloud_hidden_space": (True, "space hidden behind what the cameras saw is occupied (camera clouds, "
                                 "with camera/<name>/pose and camera_info; docs/planning.md)"),
    "cloud_shadow_px": (SHADOW_PX, "depth of that hidden layer in pixel footprints (0: all of it, down to the table)"),
    "cloud_hidden_refine": (HIDDEN_REFINE, "times the hidden cells a camera could not certify free are halved "
                                           "and certified again (0: 1 cm cells; 2: 2.5 mm, ~3x the preparation)"),
    "velocity_scale": (0.5, "fraction of the Panda's V/A/J limits used for timing"),
    "dt": (0.02, "trajectory sample period (s)"),
    "execute_timeout": (60.0, "longest wait for execute_trajectory (s)"),
    "seed": (0, "OMPL/IK random seed (0 = nondeterministic)"),
}


MAX_TIMEOUT = 600.0     # s: the longest planning budget a request may ask for
MAX_OBJECTS = 512       # scene objects per request
JOINT_SLACK = 1e-3      # rad: start configurations this far past a limit are still accepted


def scene_boxes(objects) -> dict[str, Box]:
    """SceneObject[] -> {id: Box}; objects without a pose or half extents are skipped. Ids must be
    unique names, poses and half extents finite (half extents >= 0) and within V.MAX_REACH."""
    if len(objects) > MAX_OBJECTS:
        raise InvalidInputError(f"{len(objects)} scene objects; at most {MAX_OBJECTS} are accepted")
    out = {}
    for o in objects:
        oid = V.name("object id", o.id, reason="INVALID_REQUEST")
        if oid in out:
            raise InvalidInputError(f"object id {oid!r} appears twice")
        if not o.has_pose or len(o.half_extents) != 3:
            continue
        p, q = convert.pose_arrays_from_msg(o.pose)
        pose = validate_pose(p, q, f"object {o.id}")
        V.finite(f"object {oid} distance from the base", np.linalg.norm(pose.position), 0.0, V.MAX_REACH)
        half = V.finite_array(f"object {oid} half_extents", o.half_extents, length=3)
        if np.any(half < 0) or np.any(half > V.MAX_REACH):
            raise InvalidInputError(f"object {oid}: half_extents must be in [0, {V.MAX_REACH}] m, got {half.tolist()}")
        out[oid] = Box(oid, pose.matrix(), half)
    return out


class PlannerNode(Node):
    def __init__(self):
        super().__init__("planner")
        for name, (default, desc) in PARAMS.items():
            self.declare_parameter(name, default, ParameterDescriptor(description=desc))
        p = {n: self.get_parameter(n).value for n in PARAMS}
        try:  # every number finite; NaN fails these checks too
            V.finite("velocity_scale", p["velocity_scale"], 0.0, 1.0, lo_open=True)
            for k in ("default_timeout", "dt", "execute_timeout", "ik_timeout"):
                V.finite(k, p[k], 0.0, MAX_TIMEOUT, lo_open=True)
            for k in ("retreat_distance", "approach_distance", "box_margin", "cloud_margin"):
                V.finite(k, p[k], 0.0, 1.0)
            V.finite("cloud_shadow_px", p["cloud_shadow_px"], 0.0, 1000.0)
            V.finite("cloud_hidden_refine", p["cloud_hidden_refine"], 0, MAX_REFINE)
        except InvalidInputError as e:
            raise ParameterError(str(e.args[0])) from None
        self.p = p
        seed = int(p["seed"]) or None
        self.kin = PandaKinematics()
        self.cm = CollisionModel(self.kin, margin=p["box_margin"], cloud_margin=p["cloud_margin"])
        self.ik = IKSolver(self.kin, rng=seed)
        try:  # MotionPlanner validates its own settings (the IK and RRT budgets)
            self.planner = MotionPlanner(self.kin, self.ik, self.cm, p["retreat_distance"],
                                         p["approach_distance"], ik_timeout=p["ik_timeout"],
                                         ik_iterations=p["ik_iterations"], rrt_iterations=p["rrt_iterations"],
                                         velocity_scale=p["velocity_scale"], dt=p["dt"], seed=seed)
        except InvalidInputError as e:
            raise ParameterError(str(e.args[0])) from None
        self.planner.warm_up()
        self._boxes: dict[str, Box] = {}
        self._specs: dict = {}   # {id: ObjectSpec} of the scene objects a task defines (their parts)
        # Readers are made on the first request that needs them: a request with start_positions and
        # SOURCE_SCENE (datagen's) reads nothing, and a reader the driver must deliver every period
        # to costs the graph's hot loop even if it is never read.
        self._clouds: dict[str, LatestMessage] | None = None
        self._camera_meta: dict[str, LatestMessage] = {}
        self._joints: LatestMessage | None = None
        self._articulated: dict = {}  # {id: ObjectSpec} of the scene's articulated objects (a lid, a drawer)
        self._object_joints: ObjectJointReader | None = None  # the driver's object_joint_states, from the first

        state_group = ReentrantCallbackGroup()
        self.markers = self.create_publisher(MarkerArray, "planner/path_markers", LATCHED)
        self.exec_client = ActionClient(self, ExecuteTrajectory, "execute_trajectory",
                                        callback_group=state_group)
        self.create_service(PlanToPose, "plan_to_pose", self._on_plan,
                            callback_group=MutuallyExclusiveCallbackGroup())
        self.get_logger().info("planner ready")

    # -- state -------------------------------------------------------------------------------
    def _current_q(self, timeout: float = 2.0) -> np.ndarray | None:
        """The arm configuration from the newest joint_states (waiting up to `timeout` s for one)."""
        if self._joints is None:  # a fresh reader must first match the driver, then see a period
            self._joints, timeout = LatestMessage(self, JointState, "joint_states"), max(timeout, 3.0)
        msg = self._joints.latest(timeout)
        if msg is None:
            return None
        idx = {n: i for i, n in enumerate(msg.name)}
        if not all(j in idx for j in ARM_JOINTS) or len(msg.position) != len(msg.name):
            return None
        return np.array([msg.position[idx[j]] for j in ARM_JOINTS])

    def _cloud(self) -> tuple[np.ndarray, list[DepthView]]:
        """The perception obstacle cloud when there is one, else the camera clouds fused; clouds in
        frames other than the world's are skipped, and only clouds in wrong frames is an error.
        With camera clouds, also their depth views (for the hidden space)."""
        wait = 0.0
        if self._clouds is None:  # first use: give the latched obstacle cloud time to arrive
            self._clouds = {t: LatestMessage(self, PointCloud2, t, qos_profile_sensor_data)
                            for t in CAMERA_CLOUDS}
            self._clouds["perception/obstacles"] = LatestMessage(self, PointCloud2, "perception/obstacles", LATCHED)
            for t in CAMERA_CLOUDS:  # each cloud's camera pose and intrinsics (for its depth view)
                base = t.rsplit("/", 1)[0]
                for kind, mtype in (("pose", PoseStamped), ("camera_info", CameraInfo)):
                    self._camera_meta[f"{base}/{kind}"] = LatestMessage(self, mtype, f"{base}/{kind}",
                                                                        qos_profile_sensor_data)
            wait = 1.0
        msgs = {"perception/obstacles": self._clouds["perception/obstacles"].latest(wait)}  # first: the
        msgs.update({t: self._clouds[t].latest(0.0) for t in CAMERA_CLOUDS})  # cameras' frames came meanwhile
        msgs = {t: m for t, m in msgs.items() if m is not None}
        good = {t: m for t, m in msgs.items() if m.header.frame_id in WORLD_FRAMES}
        if len(good) < len(msgs) and not good:
            raise InvalidInputError("point clouds in unsupported frames: "
                                    f"{ {t: m.header.frame_id for t, m in msgs.items()} }")
        if "perception/obstacles" in good:  # task objects removed: no views (they would shadow them)
            return convert.cloud_to_points(good["perception/obstacles"]), []
        clouds = {t: convert.cloud_to_points(m) for t, m in good.items()}
        views = [v for t, m in good.items() if self.p["cloud_hidden_space"]
                 for v in [self._view(t, m, clouds[t])] if v is not None]
        return (np.vstack(list(clouds.values())) if clouds else np.empty((0, 3))), views

    def _view(self, topic: str, msg: PointCloud2, points: np.ndarray) -> DepthView | None:
        """The depth view of an organized camera cloud: its camera's pose and K with the same stamp
        (camera/<name>/pose, camera/<name>/camera_info); None, with a warning, if there are none."""
        base = topic.rsplit("/", 1)[0]
        same = lambda m: m is not None and m.header.stamp == msg.header.stamp  # noqa: E731
        pose = self._camera_meta[f"{base}/pose"].wait_for(same, 0.2)
        info = self._camera_meta[f"{base}/camera_info"].wait_for(same, 0.2)
        if msg.height < 2 or pose is None or info is None or (info.height, info.width) != (msg.height, msg.width):
            self.get_logger().warning(f"{topic}: no organized cloud with its camera pose and camera_info "
                                      "of the same stamp; its hidden space is not marked")
            return None
        T = convert.pose_from_msg(pose.pose).matrix()
        return DepthView.from_organized(points.reshape(msg.height, msg.width, 3), np.reshape(info.k, (3, 3)), T)

    def _link_boxes(self, obstacles: dict[str, Box]) -> list[Box]:
        """Articulated objects' links (a lid) at the driver's `object_joint_states` values: obstacles where
        they are now. Without a value (no driver topic) a joint is at its reset value, with a warning."""
        if not self._articulated:
            return []
        if self._object_joints is None:
            self._object_joints = ObjectJointReader(self)
        joints = self._object_joints.values()
        if joints is None:
            self.get_logger().warning("no object_joint_states: articulated links at their reset values")
        return scene_link_boxes(self._articulated, obstacles, joints)

    def _parts(self, box: Box) -> list[Box]:
        """An object's obstacle boxes: one per primitive part where its task defines it (a drawer's walls,
        a nut's ring: the space between them stays free, as in generation in-process), else its box."""
        spec = self._specs.get(box.name)
        if spec is None:
            return [box]
        return [Box(box.name, box.pose @ Tp, h) for Tp, h in part_boxes(spec)]

    def _attached(self, box: Box, T_ee_obj: np.ndarray) -> AttachedObject:
        """The held object as spheres filling its parts on a 1 cm grid (attached_from_parts, as generation
        in-process), else its box on the planner's coarse 3 cm grid."""
        spec = self._specs.get(box.name)
        if spec is None:
            return AttachedObject.from_box(box.name, box.half_extents, T_ee_obj)
        return attached_from_parts(spec, T_ee_obj)

    # -- service -----------------------------------------------------------------------------
    def _on_plan(self, req: PlanToPose.Request, resp: PlanToPose.Response):
        t0 = time.perf_counter()
        try:
            status, msg, result = self._plan(req)
        except SkillGenError as e:
            status, msg, result = PlanStatus.INVALID_REQUEST, str(e), None
        except Exception as e:  # noqa: BLE001 -- a bug must not take the service down
            self.get_logger().error(f"plan_to_pose failed: {traceback.format_exc()}")
            status, msg, result = PlanStatus.INVALID_REQUEST, f"internal error: {e!r}", None
        resp.status = int(status)
        resp.status_name = status.name
        resp.message = msg
        if result is not None:
            for phase, sec in result.timings.items():
                resp.timings.append(_timing(phase, sec))
        if result is not None and result.ok:
            tr = result.trajectory
            resp.trajectory = convert.trajectory_to_msg(ARM_JOINTS, tr.times, tr.positions,
                                                        tr.velocities, tr.accelerations, "world")
            resp.trajectory.header.stamp = self.get_clock().now().to_msg()
            self._publish_markers(result)
            if req.execute:
                ok, why = self._execute(resp.trajectory)
                if not ok:
                    resp.status = PlanToPose.Response.EXECUTION_FAILED
                    resp.status_name = "EXECUTION_FAILED"
                    resp.message = why
        self.get_logger().info(f"plan_to_pose: {resp.status_name} in {time.perf_counter() - t0:.3f} s"
                               f" ({resp.message})")
        return resp

    def _plan(self, req):
        if len(req.objects):
            self._boxes = scene_boxes(req.objects)
            self._articulated = {o.id: a for o in req.objects if o.id in self._boxes
                                 for a in [articulated_object(o.type, o.id)] if a is not None}
            self._specs = {o.id: s for o in req.objects if o.id in self._boxes
                           for s in [scene_object_spec(o.type, o.id, o.half_extents)] if s is not None}
        t = req.target.header.frame_id
        if t not in WORLD_FRAMES:
            raise InvalidInputError(f"target frame {t!r} unsupported (use world)")
        p, q = convert.pose_arrays_from_msg(req.target.pose)
        target = validate_pose(p, q, "target")
        V.finite("target distance from the base", np.linalg.norm(target.position), 0.0, V.MAX_REACH)
        for label in ("attached_object", "manipulated_object"):
            V.name(label, getattr(req, label), allow_empty=True)
        if req.mode not in (PlanToPose.Request.TRANSIT, PlanToPose.Request.TRANSFER):
            raise InvalidInputError(f"unknown mode {req.mode}")
        if req.collision_source not in (PlanToPose.Request.SOURCE_SCENE,
                                        PlanToPose.Request.SOURCE_POINT_CLOUD):
            raise InvalidInputError(f"unknown collision_source {req.collision_source}")
        timeout = V.finite("timeout", req.timeout, hi=MAX_TIMEOUT)  # NaN/inf refused, not defaulted
        timeout = timeout if timeout > 0 else self.p["default_timeout"]  # <= 0: the default (srv)
        if len(req.start_positions):
            q0 = V.finite_array("start_positions", req.start_positions, length=7, reason="INVALID_REQUEST")
            if np.any(q0 < Q_LOWER - JOINT_SLACK) or np.any(q0 > Q_UPPER + JOINT_SLACK):
                raise InvalidInputError(f"start_positions {np.round(q0, 4).tolist()} are outside the joint limits")
        else:
            q0 = self._current_q()
            if q0 is None:
                raise InvalidInputError("no start_positions and no joint_states within 2 s")
        boxes = dict(self._boxes)
        T0 = self.kin.fk(q0)
        attached = None
        mode = Mode.TRANSIT if req.mode == PlanToPose.Request.TRANSIT else Mode.TRANSFER
        if mode is Mode.TRANSFER:
            box = boxes.get(req.attached_object)
            if box is None:
                raise InvalidInputError(f"attached object {req.attached_object!r} not in the scene")
            attached = self._attached(box, np.linalg.inv(T0) @ box.pose)
        obstacles = {k: b for k, b in boxes.items() if attached is None or k != attached.name}
        links = self._link_boxes(obstacles)
        solids = [p for b in obstacles.values() for p in self._parts(b)]
        if req.collision_source == PlanToPose.Request.SOURCE_SCENE:
            self.cm.set_boxes(solids + links)
            self.cm.set_point_cloud(np.empty((0, 3)))
        else:
            self.cm.set_boxes(solids + links, as_obstacles=False)
            points, views = self._cloud()
            points = np.vstack([points, box_points(links)])  # perception's cloud dropped the recognized machine
            self.cm.set_point_cloud(points, self_filter_q=q0, attached=attached,
                                    fill_below=bool(self.p["cloud_fill_below"]), views=views,
                                    shadow_px=float(self.p["cloud_shadow_px"]) or None,
                                    hidden_refine=int(self.p["cloud_hidden_refine"]))
        manipulated = req.manipulated_object or None
        if manipulated is not None and manipulated not in boxes:
            raise InvalidInputError(f"manipulated object {manipulated!r} not in the scene")
        parts = solids + links  # an articulated object's links too: an opened drawer's tray
        released = _containing(list(obstacles.values()) + links, T0[:3, 3])  # the hand in a nut's hole too
        start_support = goal_support = "table"
        if attached is not None:
            start_support = support_below(parts, boxes[attached.name].pose[:3, 3]) or "table"
            T_obj_goal = target.matrix() @ (np.linalg.inv(T0) @ boxes[attached.name].pose)
            goal_support = support_below(parts, T_obj_goal[:3, 3]) or "table"
        released_support = None
        if released is not None:  # what it was put on or into (a peg through a nut, a bin)
            others = [b for b in parts if b.name != released]
            c = obstacles[released].pose[:3, 3]
            released_support = _containing(others, c) or support_below(others, c)
        seed = (int(req.seed), int(req.plan_index)) if req.seeded else None
        movable = tuple(k for k, spec in self._specs.items() if not spec.is_fixture)  # as generation in-process
        result = self.planner.plan(q0, target, mode, attached, manipulated, released,
                                   start_support, goal_support, timeout, released_support=released_support,
                                   seed=seed, extras=bool(getattr(req, "extras", True)), movable=movable)
        return result.status, result.message, result

    # -- output ------------------------------------------------------------------------------
    def _publish_markers(self, result):
        if self.markers.get_subscription_count():  # else FK of every point and Point messages for nobody
            self.markers.publish(path_markers(self.kin, result, self.get_clock().now().to_msg()))

    def _execute(self, traj_msg) -> tuple[bool, str]:
        if not self.exec_client.wait_for_server(timeout_sec=10.0):  # discovery can be slow
            return False, "execute_trajectory action server not available"
        goal = ExecuteTrajectory.Goal(trajectory=traj_msg)
        fut = self.exec_client.send_goal_async(goal)
        if not wait_future(fut, 5.0) or not fut.result().accepted:
            return False, "execute_trajectory goal rejected"
        res_fut = fut.result().get_result_async()
        if not wait_future(res_fut, self.p["execute_timeout"]):
            return False, "execute_trajectory timed out"
        r = res_fut.result().result
        if r.error_code != ExecuteTrajectory.Result.SUCCESSFUL:
            return False, f"execution failed ({r.error_code}): {r.error_string}"
        return True, ""


def _timing(phase: str, seconds: float) -> PhaseTiming:
    return PhaseTiming(phase=phase, seconds=float(seconds))


def _containing(boxes: list[Box], point, pad: float = 0.02) -> str | None:
    """The name of the first box holding `point` (within `pad`)."""
    for b in boxes:
        if b.contains(np.asarray(point, float)[None], pad)[0]:
            return b.name
    return None


def main(args=None) -> int:
    return run_node(PlannerNode, args)


if __name__ == "__main__":
    sys.exit(main())

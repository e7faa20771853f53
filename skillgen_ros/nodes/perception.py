"""perception node: object poses and the obstacle cloud from the front camera (assumption A3).

Service `estimate_poses` (EstimatePoses) runs core.perception.estimate_poses on the latest
`camera/front/points` (optionally fused with `camera/wrist/points`) and publishes the result on
`perception/object_poses` (ObjectPoseArray), `perception/obstacles` (PointCloud2) and
`perception/markers` (MarkerArray), all reliable + transient local. The camera position used by
the visibility score comes from `camera/front/pose` (PoseStamped, world frame) when a driver
publishes it, else from the `camera_position` parameter. Camera topics are read on demand, the
newest message at request time (nodes/latest.py): a cloud is decoded only when it is used, and
frames nobody asks for cost this node nothing. A cloud's age (`max_cloud_age`) is the node clock
minus its stamp (use_sim_time with a lockstep driver).

Which objects to look for comes from the scene's task: parameter `task` (settable at run time with
`ros2 param set`), or a std_msgs/String on `perception/set_task` (reliable, transient local;
"Square" or "Square/D1_clutter") that the orchestrator publishes after each reset_scene. Without a
task the service answers NO_SCENE.

mode = "estimate" (default) estimates from the cloud. mode = "ground_truth" answers with the sim's
`sim/ground_truth/object_poses` instead: an explicit ablation chosen by parameter, never a
fallback; its status is NO_DATA until ground truth has arrived.

For a task with articulated objects the node reads the driver's `object_joint_states` (latched), so that
an object inside a fixture it found (Coffee Prep's pod in the opened drawer) is looked for again without
the fixture's points, its links posed at those values (core/perception/fixtures.py).
"""
from __future__ import annotations

import sys
import threading

import numpy as np
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.time import Time
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import String
from visualization_msgs.msg import Marker, MarkerArray

from skillgen_interfaces.msg import ObjectPose, ObjectPoseArray, PhaseTiming
from skillgen_interfaces.srv import EstimatePoses
from skillgen_ros.core import validation as V
from skillgen_ros.core.errors import InvalidInputError, ParameterError, SkillGenError
from skillgen_ros.core.perception.fixtures import SceneFixtures, estimate_with_fixtures
from skillgen_ros.core.perception.models import models_for_objects
from skillgen_ros.core.perception.pipeline import EstimatedPose, PerceptionParams, PerceptionStatus
from skillgen_ros.core.perception.pose import PoseParams
from skillgen_ros.nodes.convert import cloud_to_points, points_to_cloud, pose_from_msg, pose_to_msg
from skillgen_ros.nodes.driver_joints import ObjectJointReader
from skillgen_ros.nodes.latest import LatestMessage
from skillgen_ros.nodes.runtime import run_node
from skillgen_ros.nodes.state_history import ns

S = PerceptionStatus
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
MODES = ("estimate", "ground_truth")


class PerceptionNode(Node):
    def __init__(self):
        super().__init__("perception")
        d = ParameterDescriptor
        self.declare_parameter("mode", "estimate", d(description="estimate | ground_truth (explicit ablation)"))
        self.declare_parameter("task", "", d(description="task whose objects to look for; '' until set"))
        self.declare_parameter("world_frame", "world", d(description="frame clouds must be in"))
        self.declare_parameter("camera_position", [1.35, 0.0, 0.70],
                               d(description="front camera position (world) for the visibility score; [] = from above"))
        self.declare_parameter("use_wrist", False, d(description="fuse camera/wrist/points with the front cloud"))
        self.declare_parameter("max_cloud_age", 0.0, d(description="s; clouds older than this (node clock minus stamp) give NO_DATA; 0 = any age"))
        self.declare_parameter("workspace_lo", [0.2, -0.5, -0.15], d(description="workspace box min (world, m)"))
        self.declare_parameter("workspace_hi", [1.0, 0.5, 0.3], d(description="workspace box max (world, m)"))
        self.declare_parameter("voxel", 0.0025, d(description="m; object-cloud voxel size"))
        self.declare_parameter("table_distance", 0.004, d(description="m; RANSAC table inlier band"))
        self.declare_parameter("min_object_height", 0.005, d(description="m above the table that is not table"))
        self.declare_parameter("dbscan_eps", 0.008, d(description="m; DBSCAN neighbourhood"))
        self.declare_parameter("dbscan_min_points", 5, d(description="DBSCAN core-point count"))
        self.declare_parameter("min_cluster_points", 30, d(description="smaller clusters are noise"))
        self.declare_parameter("accept_score", 0.35, d(description="fitness*coverage to accept an object"))
        self.declare_parameter("inlier_distance", 0.004, d(description="m; scoring gate"))
        self.declare_parameter("yaw_steps", 24, d(description="yaw hypotheses per full turn"))
        self.declare_parameter("global_registration", False, d(description="add FPFH+RANSAC 6-DOF hypotheses"))
        self.declare_parameter("remove_known_objects", True, d(description="obstacle cloud without task objects"))
        self.declare_parameter("obstacle_volume", True, d(description="voxel-hull volumes instead of raw points"))
        self.declare_parameter("obstacle_voxel", 0.01, d(description="m; obstacle volume voxel"))
        self._lock = threading.Lock()
        self._truth: ObjectPoseArray | None = None
        self._models: dict = {}
        self._model_cache: dict[str, dict] = {}  # task -> its object models
        self._task = ""
        self._object_joints: ObjectJointReader | None = None  # the driver's object_joint_states, on first need
        self._fixtures = SceneFixtures()  # fixtures' poses seen in this scene (core/perception/fixtures.py)
        self._read_params()
        self.add_on_set_parameters_callback(self._on_params)

        self._front = LatestMessage(self, PointCloud2, "camera/front/points", qos_profile_sensor_data)
        self._wrist = LatestMessage(self, PointCloud2, "camera/wrist/points", qos_profile_sensor_data)
        self._camera_pose = LatestMessage(self, PoseStamped, "camera/front/pose", qos_profile_sensor_data)
        self.create_subscription(String, "perception/set_task", self._on_set_task, LATCHED)
        if self.mode == "ground_truth":
            self.create_subscription(ObjectPoseArray, "sim/ground_truth/object_poses", self._on_truth, LATCHED)
        self.pub_poses = self.create_publisher(ObjectPoseArray, "perception/object_poses", LATCHED)
        self.pub_obstacles = self.create_publisher(PointCloud2, "perception/obstacles", LATCHED)
        self.pub_markers = self.create_publisher(MarkerArray, "perception/markers", LATCHED)
        self.create_service(EstimatePoses, "estimate_poses", self._on_estimate)
        task = self.get_parameter("task").value
        if task:
            self._set_task(task)
        self.get_logger().info(f"perception ready: mode={self.mode}, task={self._task or '(none)'}")

    # ------------------------------------------------------------------ parameters
    def _read_params(self) -> None:
        g = lambda n: self.get_parameter(n).value  # noqa: E731
        mode = g("mode")
        if mode not in MODES:
            raise ParameterError(f"mode must be one of {MODES}, got {mode!r}")
        cam = list(g("camera_position") or [])
        lo, hi = list(g("workspace_lo")), list(g("workspace_hi"))
        try:  # every number finite and in range (NaN fails each check)
            if cam:
                V.finite_array("camera_position", cam, length=3)
            V.finite_array("workspace_lo", lo, length=3)
            V.finite_array("workspace_hi", hi, length=3)
            if not all(a < b for a, b in zip(lo, hi)):
                raise InvalidInputError(f"workspace_lo {lo} / workspace_hi {hi}: need lo < hi per axis")
            for name in ("voxel", "table_distance", "dbscan_eps", "inlier_distance", "obstacle_voxel"):
                V.finite(name, g(name), 0.0, 1.0, lo_open=True)
            V.finite("min_object_height", g("min_object_height"), 0.0, 1.0)
            V.finite("max_cloud_age", g("max_cloud_age"), 0.0)
            V.finite("accept_score", g("accept_score"), 0.0, 1.0)
            for name in ("dbscan_min_points", "min_cluster_points", "yaw_steps"):
                V.finite(name, g(name), 1, 1_000_000)
        except InvalidInputError as e:
            raise ParameterError(str(e.args[0])) from None
        self.mode = mode
        self.world_frame = g("world_frame")
        self.camera = np.array(cam, float) if cam else None
        self.use_wrist = bool(g("use_wrist"))
        self.max_age = float(g("max_cloud_age"))
        self.params = PerceptionParams(
            world_frame=self.world_frame, workspace_lo=tuple(lo), workspace_hi=tuple(hi),
            voxel=g("voxel"), table_distance=g("table_distance"), min_object_height=g("min_object_height"),
            dbscan_eps=g("dbscan_eps"), dbscan_min_points=g("dbscan_min_points"),
            min_cluster_points=g("min_cluster_points"), accept_score=g("accept_score"),
            remove_known_objects=g("remove_known_objects"), obstacle_volume=g("obstacle_volume"),
            obstacle_voxel=g("obstacle_voxel"),
            pose=PoseParams(inlier_distance=g("inlier_distance"), yaw_steps=g("yaw_steps"),
                            global_registration=g("global_registration")))

    def _on_params(self, params) -> SetParametersResult:
        for p in params:
            if p.name == "task":
                try:
                    self._set_task(p.value)
                except SkillGenError as e:
                    return SetParametersResult(successful=False, reason=str(e))
            elif p.name != "use_sim_time":
                return SetParametersResult(successful=False, reason=f"{p.name} is read at start-up; restart to change it")
        return SetParametersResult(successful=True)

    def _set_task(self, name: str) -> bool:
        """Switch to the task's object models; False if it already was the task. Models are built
        once per task (sampling the meshes takes a fraction of a second, and datagen names the task
        when a run starts)."""
        from skillgen_ros.core.tasks import get_task  # task suite: pure, no pybullet
        task = name.split("/")[0].strip()
        if task == self._task:
            return False
        if task not in self._model_cache:
            self._model_cache[task] = models_for_objects(get_task(task).objects) if task else {}
        with self._lock:
            self._task, self._models = task, self._model_cache[task]
        return True

    # ------------------------------------------------------------------ inputs
    def _age(self, msg) -> float:
        return (self.get_clock().now() - Time.from_msg(msg.header.stamp)).nanoseconds * 1e-9

    def _fresh(self, msg) -> bool:
        return msg is not None and (self.max_age <= 0 or self._age(msg) <= self.max_age)

    def _on_truth(self, msg: ObjectPoseArray) -> None:
        with self._lock:
            self._truth = msg

    def _on_set_task(self, msg: String) -> None:
        with self._lock:
            self._fixtures.clear()  # a new task; a request's `scene` tells a new scene of the same task
        try:
            if self._set_task(msg.data):
                self.get_logger().info(f"task set to {self._task!r}")
        except SkillGenError as e:
            self.get_logger().error(f"perception/set_task: {e}")

    # ------------------------------------------------------------------ service
    def _on_estimate(self, req: EstimatePoses.Request, res: EstimatePoses.Response) -> EstimatePoses.Response:
        try:
            scene = ns(req.scene) or None  # the reset's stamp names the scene; zero: the node's own memory
            status, msg, poses, obstacles, timings = self._estimate(list(req.object_ids), req.newer_than, scene)
        except Exception as e:  # noqa: BLE001 - a bug must not take the node down; report it
            self.get_logger().error(f"estimate_poses failed: {e!r}")
            status, msg, poses, obstacles, timings = S.INTERNAL_ERROR, repr(e), {}, np.zeros((0, 3)), {}
        stamp = self.get_clock().now().to_msg()
        res.status, res.status_name, res.message = int(status), status.name, msg
        res.poses = [object_pose_msg(i, e) for i, e in poses.items()]
        res.obstacles = points_to_cloud(obstacles, self.world_frame, stamp)
        res.timings = [PhaseTiming(phase=k, seconds=float(v)) for k, v in timings.items()]
        if status in (S.OK, S.OBJECT_MISSING, S.AMBIGUOUS):
            arr = ObjectPoseArray(objects=res.poses)
            arr.header.frame_id, arr.header.stamp = self.world_frame, stamp
            self.pub_poses.publish(arr)
            self.pub_obstacles.publish(res.obstacles)
            self.pub_markers.publish(markers(poses, self._models, self.world_frame, stamp))
        return res

    def _front_cloud(self, newer_than=None, wait: float = 1.0):
        """The newest front cloud; with a nonzero `newer_than`, waiting up to `wait` s for one
        stamped at or after it (None if none comes)."""
        floor = Time() if newer_than is None else Time.from_msg(newer_than)
        if floor.nanoseconds == 0:
            return self._front.latest()
        return self._front.wait_for(lambda m: m is not None and Time.from_msg(m.header.stamp) >= floor, wait)

    def _estimate(self, object_ids: list[str], newer_than=None, scene=None):
        if len(object_ids) > V.MAX_ITEMS or any(not i or len(i) > V.MAX_NAME for i in object_ids):
            # EstimatePoses has no INVALID_REQUEST status; a name no task can have is a missing object
            return (S.OBJECT_MISSING, f"object_ids must be at most {V.MAX_ITEMS} non-empty names of at most "
                    f"{V.MAX_NAME} characters", {}, np.zeros((0, 3)), {})
        with self._lock:
            models, truth, task, camera = dict(self._models), self._truth, self._task, self.camera
        pose = self._camera_pose.latest()
        if pose is not None and pose.header.frame_id == self.world_frame:
            camera = np.array([pose.pose.position.x, pose.pose.position.y, pose.pose.position.z])
        none = np.zeros((0, 3))
        if not task:
            return S.NO_SCENE, "no task set (parameter task or topic perception/set_task)", {}, none, {}
        unknown = [i for i in object_ids if i not in models]
        if unknown:
            return S.OBJECT_MISSING, f"task {task} has no object(s) {unknown}", {}, none, {}
        if self.mode == "ground_truth":
            if truth is None:
                return S.NO_DATA, "ground_truth mode: nothing on sim/ground_truth/object_poses yet", {}, none, {}
            wanted = object_ids or list(models)
            got = {o.id: EstimatedPose(pose_from_msg(o.pose), 1.0, o.type or models[o.id].type)
                   for o in truth.objects if o.id in wanted}
            missing = [i for i in wanted if i not in got]
            if missing:
                return S.OBJECT_MISSING, f"ground truth lacks {missing}", got, none, {}
            return S.OK, f"ground truth for {len(got)} object(s)", got, none, {}
        front = self._front_cloud(newer_than)
        if not self._fresh(front):
            return S.NO_DATA, "no recent cloud on camera/front/points", {}, none, {}
        if front.header.frame_id != self.world_frame:
            return (S.WRONG_FRAME, f"cloud is in frame {front.header.frame_id!r}, expected {self.world_frame!r}",
                    {}, none, {})
        pts = cloud_to_points(front)
        wrist = self._wrist.latest() if self.use_wrist else None
        if self._fresh(wrist):
            if wrist.header.frame_id == self.world_frame:
                pts = np.concatenate([pts, cloud_to_points(wrist)])
        from skillgen_ros.core.tasks import get_task  # task suite: pure, no pybullet
        specs = {o.id: o for o in get_task(task).objects}
        joints = None
        if any(o.joints for o in specs.values()):  # an object inside a fixture (core/perception/fixtures.py)
            if self._object_joints is None:
                self._object_joints = ObjectJointReader(self)
            joints = self._object_joints.values()
        with self._lock:
            known = self._fixtures.known(scene)
        r = estimate_with_fixtures(pts, models, specs, self.params, camera, object_ids or None, joints, known=known)
        with self._lock:  # fixtures do not move within a scene
            self._fixtures.update(scene, r, specs)
        return r.status, r.message, r.poses, r.obstacles, r.timings


def object_pose_msg(oid: str, e: EstimatedPose) -> ObjectPose:
    return ObjectPose(id=oid, type=e.object_type, pose=pose_to_msg(e.pose), confidence=float(e.confidence))


def markers(poses: dict, models: dict, frame: str, stamp) -> MarkerArray:
    """A mesh and a label per recognized object (RViz / Foxglove)."""
    out = MarkerArray()
    clear = Marker(action=Marker.DELETEALL)
    clear.header.frame_id = frame
    out.markers.append(clear)
    for k, (oid, e) in enumerate(sorted(poses.items())):
        m = Marker(ns="objects", id=2 * k, type=Marker.MESH_RESOURCE, action=Marker.ADD, pose=pose_to_msg(e.pose))
        m.header.frame_id, m.header.stamp = frame, stamp
        m.mesh_resource = f"file://{models[oid].source}" if oid in models and models[oid].source else ""
        if not m.mesh_resource:
            m.type = Marker.SPHERE
        m.scale.x = m.scale.y = m.scale.z = 1.0 if m.type == Marker.MESH_RESOURCE else 0.02
        m.color.r, m.color.g, m.color.b, m.color.a = 0.2, 0.8, 0.2, 0.8
        t = Marker(ns="labels", id=2 * k + 1, type=Marker.TEXT_VIEW_FACING, action=Marker.ADD,
                   pose=pose_to_msg(e.pose), text=f"{oid} {e.confidence:.2f}")
        t.header.frame_id, t.header.stamp = frame, stamp
        t.pose.position.z += 0.08
        t.scale.z = 0.02
        t.color.r = t.color.g = t.color.b = t.color.a = 1.0
        out.markers += [m, t]
    return out


def main(args=None) -> int:
    return run_node(PerceptionNode, args, name="perception")


if __name__ == "__main__":
    sys.exit(main())

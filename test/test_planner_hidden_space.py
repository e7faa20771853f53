"""planner node: an organized camera cloud with its camera pose and camera_info becomes a depth
view, and the space hidden behind what it saw is occupied (issue 19), as in-process."""
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import pybullet as pb
import yaml
from pybullet_utils.bullet_client import BulletClient
from rclpy.executors import MultiThreadedExecutor
from rclpy.qos import qos_profile_sensor_data
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import CameraInfo, PointCloud2

from skillgen_interfaces.srv import PlanToPose
from conftest import client_node
from skillgen_ros.answered import first_answer, sleep_until_done
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.robot import Q_HOME, TABLE_Z
from skillgen_ros.core.sim import camera as cam
from skillgen_ros.nodes import convert

PARAMS = Path(__file__).resolve().parents[1] / "params" / "planner.yaml"


def _front_frame():
    """The sim's front camera over a tall box (top 30 cm above the table) on the planner's table."""
    p = BulletClient(connection_mode=pb.DIRECT)
    p.createMultiBody(0, p.createCollisionShape(pb.GEOM_BOX, halfExtents=[1.5, 1.5, 0.05]),
                      basePosition=[0.5, 0.0, TABLE_Z - 0.05])
    p.createMultiBody(0, p.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.08, 0.15, 0.15]),
                      basePosition=[0.56, 0.0, TABLE_Z + 0.15])
    f = cam.render(p, cam.CameraConfig("front"), cam.front_camera_pose(), np.random.default_rng(0))
    p.disconnect()
    return f


def _request(xyz):
    req = PlanToPose.Request()
    req.target.header.frame_id = "world"
    req.target.pose.position.x, req.target.pose.position.y, req.target.pose.position.z = xyz
    req.target.pose.orientation.x, req.target.pose.orientation.w = 1.0, 0.0  # gripper pointing down
    req.start_positions = [float(v) for v in Q_HOME]
    req.timeout = 5.0
    req.collision_source = PlanToPose.Request.SOURCE_POINT_CLOUD
    return req


def test_the_node_occupies_what_the_camera_could_not_see_behind_a_box(ros_domain, start_node, tmp_path):
    params = yaml.safe_load(PARAMS.read_text())
    params["planner"]["ros__parameters"]["cloud_shadow_px"] = 0.0  # all hidden space, to the table
    path = tmp_path / "planner.yaml"
    path.write_text(yaml.safe_dump(params))
    planner = start_node("planner", params=str(path))
    f = _front_frame()
    with client_node(ros_domain, "hidden_test", MultiThreadedExecutor, spin=True) as (node, _):
        pubs = {k: node.create_publisher(t, f"camera/front/{k}", qos_profile_sensor_data)
                for k, t in (("points", PointCloud2), ("pose", PoseStamped), ("camera_info", CameraInfo))}
        with_pose, stop = threading.Event(), threading.Event()

        def camera():  # a camera publishing its frames at 10 Hz, as the driver does
            while not stop.is_set():
                stamp = node.get_clock().now().to_msg()
                if with_pose.is_set():
                    pose = convert.pose_stamped(Pose.from_matrix(f.T_world_camera), "world", stamp)
                    pubs["camera_info"].publish(CameraInfo(header=pose.header, height=f.depth.shape[0],
                                                           width=f.depth.shape[1], k=f.K.reshape(-1).tolist()))
                    pubs["pose"].publish(pose)
                pubs["points"].publish(convert.points_to_cloud(f.points_world.reshape(-1, 3), "world", stamp,
                                                               organized_shape=f.depth.shape))
                time.sleep(0.1)  # the camera's 10 Hz (pacing, not synchronisation)
        t = threading.Thread(target=camera, daemon=True)
        t.start()
        try:
            cli = node.create_client(PlanToPose, "plan_to_pose")
            assert cli.wait_for_service(timeout_sec=90.0)

            def call(req):
                r = first_answer(lambda: cli.call_async(req), sleep_until_done, 60.0, each=20.0)
                assert r is not None, "no answer from plan_to_pose"
                return r
            behind = _request((0.30, 0.0, TABLE_Z + 0.10))  # in the box's shadow, 18 cm behind it
            # no camera pose yet: the cloud alone (its surfaces and the heightmap), the goal is free
            for _ in range(20):  # until the planner has read a frame (it warns that it lacks the pose)
                r = call(behind)
                assert r.status == PlanToPose.Response.SUCCESS, r.message
                if "its hidden space is not marked" in planner.output():
                    break
            assert "its hidden space is not marked" in planner.output()
            # the camera's pose and intrinsics arrive: the space hidden behind the box is occupied
            # (polled: the planner reads the newest frame, which carries them once one has arrived)
            with_pose.set()
            for _ in range(20):
                r = call(behind)
                if r.status != PlanToPose.Response.SUCCESS:
                    break
            assert r.status == PlanToPose.Response.GOAL_IN_COLLISION, r.message
        finally:
            stop.set()
            t.join()


@pytest.mark.parametrize("param", ["cloud_shadow_px:=-1.0", "cloud_shadow_px:=.nan",
                                   "cloud_hidden_refine:=-1", "cloud_hidden_refine:=9"])
def test_a_bad_shadow_depth_or_refine_parameter_exits_with_a_reason(start_node, param):
    proc = start_node("planner", "--ros-args", "-p", param)
    assert proc.proc.wait(timeout=60) == 2
    assert "INVALID_PARAMETER" in proc.stop()

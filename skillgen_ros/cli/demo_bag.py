"""Write a demonstrator rollout as a source bag (rosbag2-layout MCAP) in-process, no ROS graph.

Messages are built with the real message classes and serialized with
rclpy.serialization.serialize_message (which needs no ROS context), then written by core/bag's
BagWriter. Per step the observation topics come first, then osc_target, all stamped with the
sim time (t0 + step time); that is the layout `core/skills/bag_demos` reads back.
"""
from __future__ import annotations

from pathlib import Path

from skillgen_ros import rosenv  # noqa: F401  (AMENT_PREFIX_PATH before rclpy loads)

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from skillgen_interfaces.msg import GripperState, ObjectPose, ObjectPoseArray, OscTarget
from skillgen_ros.core.bag.writer import ANNOTATIONS_RECORD, BagWriter, Compression, TopicSpec, WriterOptions
from skillgen_ros.core.demonstrator.record import DemoRollout
from skillgen_ros.core.skills.annotation import Annotation, dumps_annotation
from skillgen_ros.core.skills.bag_demos import SCENE_RECORD, SOURCE_TOPICS

T0_NS = 1_700_000_000 * 10**9  # a fixed epoch so that identical rollouts give identical bags
FRAME = "world"
_RELIABLE = {"history": "keep_last", "depth": 10, "reliability": "reliable", "durability": "volatile"}


def _stamp(ns: int) -> Time:
    return Time(sec=ns // 10**9, nanosec=ns % 10**9)


def _pose(msg_pose, a) -> None:
    msg_pose.position.x, msg_pose.position.y, msg_pose.position.z = (float(v) for v in a[:3])
    (msg_pose.orientation.x, msg_pose.orientation.y, msg_pose.orientation.z,
     msg_pose.orientation.w) = (float(v) for v in a[3:7])


def step_messages(step, stamp: Time) -> list[tuple[str, object]]:
    """(relative topic, message) for one DemoStep, observations first, osc_target last."""
    js = JointState()
    js.header.stamp, js.header.frame_id = stamp, ""
    js.name = list(step.joint_names)
    js.position = [float(v) for v in step.joint_positions]
    ee = PoseStamped()
    ee.header.stamp, ee.header.frame_id = stamp, FRAME
    _pose(ee.pose, step.ee_pose)
    gs = GripperState()
    gs.header.stamp, gs.header.frame_id = stamp, FRAME
    gs.width, gs.command, gs.grasping = float(step.gripper_width), float(step.gripper_command), bool(
        step.gripper_grasping)
    op = ObjectPoseArray()
    op.header.stamp, op.header.frame_id = stamp, FRAME
    for oid, p in step.object_poses.items():
        o = ObjectPose(id=str(oid), type=str(step.object_types.get(oid, oid)), confidence=1.0)
        _pose(o.pose, p)
        op.objects.append(o)
    cmd = OscTarget()
    cmd.header.stamp, cmd.header.frame_id = stamp, FRAME
    _pose(cmd.pose, step.target)
    cmd.gripper = float(step.gripper_command)
    out = [("joint_states", js), ("ee_pose", ee), ("gripper_state", gs), ("sim/ground_truth/object_poses", op)]
    if step.object_joints:  # articulated objects' joints, as the driver's object_joint_states
        oj = JointState()
        oj.header.stamp, oj.header.frame_id = stamp, FRAME
        oj.name, oj.position = list(step.object_joints), [float(v) for v in step.object_joints.values()]
        out.append(("object_joint_states", oj))
    return out + [("osc_target", cmd)]


def scene_record(rollout: DemoRollout, demo: str) -> dict[str, str]:
    return {"task": rollout.task, "variant": rollout.variant, "seed": str(rollout.seed), "demo": demo,
            "demonstrator_seed": str(rollout.demonstrator_seed), "success": str(bool(rollout.success)).lower(),
            "made_by": "skillgen demos make (scripted demonstrator, pybullet SimWorld)"}


def write_demo_bag(path, rollout: DemoRollout, annotation: Annotation | None = None,
                   compression: str = "zstd", skip_topics=()) -> Path:
    """Write one rollout as a bag directory at `path` (which must not exist yet). Returns the path.

    `skip_topics` leaves topics out (tests use it to build bags with a topic missing).
    """
    path = Path(path)
    w = BagWriter(path, WriterOptions(compression=Compression.parse(compression), chunk_size=4 << 20,
                                      max_chunk_age_s=1e9, metadata_interval_s=1e9))
    try:
        for rel, typ in SOURCE_TOPICS.items():  # the demonstrator's poses are the sim's, not perception's
            articulated = rel == "object_joint_states" and any(st.object_joints for st in rollout.steps)
            if rel not in skip_topics and rel != "perception/object_poses" and (rel != "object_joint_states"
                                                                               or articulated):
                w.add_topic(TopicSpec("/" + rel, typ, (_RELIABLE,)))
        for step in rollout.steps:
            ns = T0_NS + int(round(step.time * 1e9))
            for k, (rel, msg) in enumerate(step_messages(step, _stamp(ns))):
                if rel not in skip_topics:
                    w.write("/" + rel, serialize_message(msg), ns + k)
        w.add_metadata(SCENE_RECORD, scene_record(rollout, path.name))
        if annotation is not None:
            w.add_metadata(ANNOTATIONS_RECORD, {"yaml": dumps_annotation(annotation)})
    finally:
        w.close()
    return path

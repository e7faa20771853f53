"""Foxglove scene (docs/foxglove.md): Panda TF from joint states, tf2_msgs written by schema, the
robot model and object markers, and the recorder writing them into a bag that third-party
decoders read with every frame connected to `world`."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import JointState

from _foxglove_checks import decode_all, tf_parents, unconnected
from conftest import wait_for
from skillgen_interfaces.msg import ObjectPose, ObjectPoseArray
from skillgen_ros.core.bag.reader import BagReader
from skillgen_ros.core.bag.schemas import schema_text
from skillgen_ros.core.bag.writer import BagWriter, TopicSpec
from skillgen_ros.core.planning.kinematics import PandaKinematics
from skillgen_ros.core.robot import ARM_JOINTS, FINGER_JOINTS, Q_HOME
from skillgen_ros.core.viz.description import resolve_package_uri, robot_description
from skillgen_ros.core.viz.messages import TF_TYPE, decode
from skillgen_ros.core.viz.robot_tf import WORLD, panda_tf
from skillgen_ros.core.viz.scene import (OBJECT_MARKERS, ROBOT_DESCRIPTION, SCENE_TOPICS, TF, TF_STATIC,
                                         ObjectPoseValue, SceneSynthesizer)

REPO = Path(__file__).resolve().parents[1]
Q = np.array([0.3, -0.5, 0.2, -2.0, 0.1, 1.7, 0.6])


def _matrix(t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(t.quaternion).as_matrix()
    T[:3, 3] = t.position
    return T


def test_panda_tf_chain_is_the_planner_forward_kinematics():
    tf = panda_tf()
    pos = dict(zip(ARM_JOINTS, Q)) | dict.fromkeys(FINGER_JOINTS, 0.03)
    edges = {t.child: t for t in tf.transforms(pos, 0) + tf.transforms(pos, 0, fixed=True)}
    assert set(edges) == set(tf.links)  # every link has exactly one parent edge
    T, frame = np.eye(4), "panda_grasptarget"
    while frame != WORLD:
        T = _matrix(edges[frame]) @ T
        frame = edges[frame].parent
    assert np.allclose(T, PandaKinematics().fk(Q), atol=1e-9)
    moving = {t.child for t in tf.transforms(pos, 0)}
    assert "panda_link1" in moving and "panda_leftfinger" in moving and "panda_hand" not in moving
    with pytest.raises(Exception, match="not finite"):
        tf.transforms({"panda_joint1": float("nan")}, 0)


def test_robot_description_meshes_resolve_and_nothing_escapes():
    urdf = robot_description()
    uris = sorted(set(u for u in urdf.split('"') if u.startswith("package://")))
    assert uris and all(u.startswith("package://franka_panda/meshes/") for u in uris)
    assert all(resolve_package_uri(u) is not None for u in uris)
    for bad in ("package://franka_panda/../../../etc/passwd", "package://other/meshes/visual/link1.obj",
                "file:///etc/passwd", "package://franka_panda/meshes/none.obj"):
        assert resolve_package_uri(bad) is None


def test_tf2_schema_comes_from_rosbags_standard_definition():
    text = schema_text(TF_TYPE)
    assert text.startswith("geometry_msgs/TransformStamped[] transforms")
    assert "MSG: geometry_msgs/TransformStamped" in text


def _objects(z: float = 0.0):
    return [ObjectPoseValue("square_nut", "square_nut", (0.5, 0.1, z), (0, 0, 0, 1)),
            ObjectPoseValue("square_peg", "square_peg", (0.6, -0.1, 0.0), (0, 0, 0, 1)),
            ObjectPoseValue("mystery", "not_a_model", (0.4, 0.0, 0.0), (0, 0, 0, 1))]


def test_synthesized_scene_bag_decodes_with_third_party_readers(tmp_path):
    synth = SceneSynthesizer()
    msgs = synth.on_joints(list(ARM_JOINTS + FINGER_JOINTS), list(Q_HOME) + [0.04, 0.04], 1_000)
    msgs += synth.on_objects(_objects(), 2_000)
    msgs += synth.on_objects(_objects(0.01), 3_000)  # same objects: no second model message
    msgs += synth.on_objects(_objects(), 3_500, estimate=True)
    msgs += synth.on_camera("front", (1.0, 0.0, 0.5), (0, 0, 0, 1), 4_000)
    msgs += synth.on_path([((0.4, 0.0, 0.2), (1, 0, 0, 0)), ((0.5, 0.1, 0.1), (0, 0, 0, 1))], 5_000)
    assert [m.topic for m in msgs].count(ROBOT_DESCRIPTION) == 1 and [m.topic for m in msgs].count(OBJECT_MARKERS) == 1
    bag = tmp_path / "scene"
    with BagWriter(bag) as w:
        for topic, (type_name, _) in SCENE_TOPICS.items():
            w.add_topic(TopicSpec(topic, type_name))
        for m in msgs:
            w.write(m.topic, m.data, m.stamp_ns)
    got = decode_all(bag)
    assert set(got) == set(SCENE_TOPICS)
    frames = set(panda_tf().links) | {"square_nut", "square_peg", "mystery", "square_nut_estimate",
                                       "camera_front_optical", "planner_goal_0", "planner_goal_1"}
    assert unconnected(frames, tf_parents(got)) == []
    markers = got[OBJECT_MARKERS][0].markers
    assert markers[0].action == 3 and {m.header.frame_id for m in markers[1:]} == {"square_nut", "square_peg", "mystery"}
    assert all(m.frame_locked for m in markers[1:])
    assert "panda_link0" in got[ROBOT_DESCRIPTION][0].data
    reset = SceneSynthesizer()
    assert decode(reset.on_joints([], [], 0)[1].data, TF_TYPE).transforms[0].header.frame_id == WORLD


def _publish_scene(node):
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    objects = node.create_publisher(ObjectPoseArray, "sim/ground_truth/object_poses", latched)
    msg = ObjectPoseArray(objects=[ObjectPose(id="square_nut", type="square_nut", confidence=1.0)])
    msg.objects[0].pose.orientation.w = 1.0
    objects.publish(msg)
    return node.create_publisher(JointState, "joint_states", 10), objects


def test_recorder_writes_the_scene_and_throttles_a_topic(tmp_path, start_node, ros_node):
    bag = tmp_path / "rec"
    rec = start_node("recorder", "--ros-args", "--params-file", str(REPO / "params" / "recorder.yaml"),
                     "-p", f"output:={bag}", "-p", "topics:=[joint_states]", "-p", "scene:=true",
                     "-p", "max_chunk_age:=0.2",
                     "-p", "throttle:=['joint_states=1000.0']")
    js_pub, _ = _publish_scene(ros_node)
    assert wait_for(lambda: js_pub.get_subscription_count() >= 2, 30), rec.output()  # raw recording + scene feed
    k = 0

    def tf_count() -> int:
        nonlocal k
        k += 1  # publish until the recorder has written TF for it: observable state, not a sleep
        js_pub.publish(JointState(name=list(ARM_JOINTS), position=[0.1 * k] * 7))
        try:
            return BagReader(bag).topics.get(TF).message_count if TF in BagReader(bag).topics else 0
        except Exception:  # noqa: BLE001 -- nothing on disk yet
            return 0

    assert wait_for(lambda: tf_count() >= 3, 60)
    out = rec.stop()
    assert rec.proc.returncode == 0, out
    got = decode_all(bag)
    assert {TF, TF_STATIC, ROBOT_DESCRIPTION, OBJECT_MARKERS, "/joint_states"} <= set(got)
    assert unconnected(set(panda_tf().links) | {"square_nut"}, tf_parents(got)) == []
    assert len(got["/joint_states"]) == 1 and len(got[TF]) >= 3  # throttled to one per 1000 s; TF from every one
    topics = BagReader(bag).topics  # latched in the metadata, as a player or Foxglove reads it
    for name, (_, latched) in SCENE_TOPICS.items():
        assert {q["durability"] for q in topics[name].qos_profiles} == {"transient_local" if latched else "volatile"}
    assert topics[TF].type_hash.startswith("RIHS01_")


def test_recorder_throttle_parameter_is_checked(start_node, tmp_path):
    for bad in ("camera/front/points", "camera/front/points=0", "camera/front/points=x", "=1.0"):
        rec = start_node("recorder", "--ros-args", "-p", f"output:={tmp_path / 'x'}", "-p", "topics:=[a]",
                         "-p", f"throttle:=['{bad}']")
        assert rec.proc.wait(30) != 0
        out = rec.stop()
        assert "throttle" in out and "Traceback" not in out, out


def _layout(name: str) -> tuple[dict, list[str], set[str]]:
    """(configById, panel ids in the layout tree, topics the panels read)."""
    import json

    layout = json.loads((REPO / "docs" / "foxglove" / name).read_text())
    panels, stack = [], [layout["layout"]]
    while stack:
        node = stack.pop()
        if isinstance(node, str):
            panels.append(node)
        else:
            stack += [node["first"], node["second"]]
    used = set()
    for pid, c in layout["configById"].items():
        used |= set(c.get("topics", {})) if pid.startswith("3D!") else set()
        used |= {c["imageMode"]["imageTopic"]} if pid.startswith("Image!") else set()
        used |= {p["value"].split(".")[0] for p in c.get("paths", [])}
        used |= {c["topicPath"].split(".")[0]} if "topicPath" in c else set()
    return layout["configById"], panels, used


def _graph_topics(graph: str) -> set[str]:
    from skillgen_ros.graphs import load_graph

    rec = dict(next(n for n in load_graph(graph) if n.exe == "recorder").parameters)
    return {"/" + t.strip() for t in rec["topics"].strip("[]").split(",")} | set(SCENE_TOPICS)


def test_layouts_panels_exist_and_read_topics_the_bags_and_the_graph_have():
    cfg, panels, used = _layout("skillgen.json")
    assert sorted(panels) == sorted(cfg)
    assert {p.split("!")[0] for p in panels} == {"3D", "Image", "Plot", "StateTransitions"}
    assert used <= _graph_topics("datagen"), used - _graph_topics("datagen")
    cfg, panels, used = _layout("teleop.json")  # live view of the teleop graph: the driver's cameras
    assert sorted(panels) == sorted(cfg) and {"/camera/front/image", "/camera/wrist/image"} <= used
    driver = {f"/camera/{c}/{k}" for c in ("front", "wrist") for k in ("image", "camera_info", "points")}
    assert used <= _graph_topics("teleop") | driver, used - _graph_topics("teleop") - driver


def test_standard_type_hash_agrees_with_rosidl_and_covers_tf2():
    from rosbags.typesys import Stores, get_typestore

    from skillgen_ros.core.bag.schemas import type_hash

    store = get_typestore(Stores.ROS2_JAZZY)
    assert type_hash("sensor_msgs/msg/JointState") == store.hash_rihs01("sensor_msgs/msg/JointState")  # from rosidl JSON
    assert type_hash(TF_TYPE) == store.hash_rihs01(TF_TYPE) and type_hash(TF_TYPE).startswith("RIHS01_")
    assert type_hash("nopkg/msg/X") == ""


def test_playing_a_whole_scene_bag_skips_tf_and_replays_the_rest(tmp_path, start_node, ros_node):
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String

    bag = tmp_path / "scene_and_note"
    tf = SceneSynthesizer().on_joints(list(ARM_JOINTS), list(Q_HOME), 1)[-1]
    with BagWriter(bag) as w:
        w.add_topic(TopicSpec("/note", "std_msgs/msg/String"))
        w.add_topic(TopicSpec(TF, TF_TYPE))
        for i in range(5):
            w.write(TF, tf.data, 1_000 + i)
            w.write("/note", serialize_message(String(data=f"n{i}")), 2_000 + i)
    notes = []
    ros_node.create_subscription(String, "/note", lambda m: notes.append(m.data), 50)
    play = start_node("player", "--ros-args", "--params-file", str(REPO / "params" / "player.yaml"),
                      "-p", f"bag:={bag}", "-p", "wait_for_subscribers:=15.0")
    assert play.proc.wait(60) == 0, play.output()
    assert wait_for(lambda: len(notes) == 5, 15) and notes == [f"n{i}" for i in range(5)]
    assert "not replaying (type not installed): /tf (tf2_msgs/msg/TFMessage)" in play.output()

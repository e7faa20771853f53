"""Bags any rosbag2 reader opens: complete v9 QoS, `skillgen bag reindex`, and every shipped bag (10 per task).

rosbags' AnyReader (like rosbag2's own YAML reader) needs all nine keys of every offered QoS
profile (issue 19: the first shipped bags lacked deadline, lifespan, liveliness, ...).
"""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader
from mcap.writer import Writer
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader, AnyReaderError
from skillgen_interfaces.msg import OscTarget

from skillgen_ros.core.bag import schemas
from skillgen_ros.core.bag.qos import PROFILE_KEYS, complete_profile
from skillgen_ros.core.bag.reader import BagReader
from skillgen_ros.core.bag.recover import reindex_bag
from skillgen_ros.core.bag.writer import BagWriter, TopicSpec
from skillgen_ros.core.errors import BagError

REPO = Path(__file__).resolve().parents[1]
SHIPPED = sorted(p for p in (REPO / "bags").glob("*/demo_*") if p.is_dir())
OLD_QOS = {"history": "keep_last", "depth": 10, "reliability": "reliable", "durability": "volatile"}
# rclpy's serialize_message reports 8 bytes past the CDR end of a JointState whose last arrays are
# empty; rosbags' deserialize rejects more than 3 such bytes, mcap_ros2's decoder accepts them.
RCLPY_PADDED = {"sensor_msgs/msg/JointState"}


def _qos_lists(bag: Path) -> list[list[dict]]:
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    return [t["topic_metadata"]["offered_qos_profiles"] for t in meta["topics_with_message_count"]]


def test_every_shipped_bag_opens_in_rosbags_with_complete_qos():
    from skillgen_ros.core.tasks import TASK_NAMES

    tasks = {bag.parent.name for bag in SHIPPED}
    assert tasks == set(TASK_NAMES) and len(SHIPPED) == 10 * len(tasks)
    for bag in SHIPPED:
        for profiles in _qos_lists(bag):
            assert profiles and all(list(p) == list(PROFILE_KEYS) for p in profiles), bag
        ours = BagReader(bag)
        with AnyReader([bag]) as r:
            assert {c.topic for c in r.connections} == set(ours.topics), bag
            assert r.message_count == ours.message_count > 0
            assert all(c.ext.offered_qos_profiles for c in r.connections), bag


def test_every_message_of_a_shipped_bag_decodes_through_rosbags_or_the_public_decoder():
    bag = SHIPPED[0]
    ours = BagReader(bag)
    decoded = 0
    with AnyReader([bag]) as r:
        for c, _, raw in r.messages():
            if c.msgtype in RCLPY_PADDED:
                continue
            r.deserialize(raw, c.msgtype)
            decoded += 1
    padded = [m for m in ours.messages() if m.type in RCLPY_PADDED]
    # the arm's 7 joints; Coffee's object_joint_states, its lid hinge
    assert all(len(ours.decode(m).position) == (1 if m.topic == "/object_joint_states" else 7) for m in padded)
    assert decoded + len(padded) == ours.message_count


def _old_style_bag(path: Path, n: int = 20) -> list[bytes]:
    """A bag as the first shipped ones were: 4-key QoS in metadata.yaml and channel metadata."""
    path.mkdir()
    payloads = []
    with open(path / "old_0.mcap", "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="old")
        sid = w.register_schema("skillgen_interfaces/msg/OscTarget", "ros2msg",
                                schemas.schema_text("skillgen_interfaces/msg/OscTarget").encode())
        cid = w.register_channel("/osc_target", "cdr", sid,
                                 {"offered_qos_profiles": yaml.safe_dump([OLD_QOS], sort_keys=False)})
        for i in range(n):
            m = OscTarget(gripper=float(i))
            payloads.append(serialize_message(m))
            w.add_message(cid, log_time=10**9 + i, publish_time=10**9 + i, data=payloads[-1], sequence=i)
        w.finish()
    meta = {"rosbag2_bagfile_information": {
        "version": 9, "storage_identifier": "mcap", "relative_file_paths": ["old_0.mcap"],
        "duration": {"nanoseconds": n - 1}, "starting_time": {"nanoseconds_since_epoch": 10**9},
        "message_count": n, "topics_with_message_count": [{"topic_metadata": {
            "name": "/osc_target", "type": "skillgen_interfaces/msg/OscTarget", "serialization_format": "cdr",
            "offered_qos_profiles": [OLD_QOS], "type_description_hash": ""}, "message_count": n}],
        "compression_format": "", "compression_mode": "",
        "files": [{"path": "old_0.mcap", "starting_time": {"nanoseconds_since_epoch": 10**9},
                   "duration": {"nanoseconds": n - 1}, "message_count": n}],
        "custom_data": {"made_by": "an old version"}, "ros_distro": "jazzy"}}
    (path / "metadata.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    return payloads


def test_reindex_repairs_an_old_bag_byte_for_byte_and_is_then_a_noop(tmp_path):
    bag = tmp_path / "old"
    payloads = _old_style_bag(bag)
    with pytest.raises(AnyReaderError, match="deadline"):
        with AnyReader([bag]):
            pass
    result = reindex_bag(bag)
    assert result.metadata_changed and len(result.rewritten) == 1
    assert (bag / "old_0.mcap.orig").is_file()  # the original is kept unless --no-backup
    with AnyReader([bag]) as r:
        got = [bytes(raw) for _, _, raw in r.messages()]
    assert got == payloads
    with open(bag / "old_0.mcap", "rb") as f:
        channel = next(iter(make_reader(f).get_summary().channels.values()))
    assert [list(p) for p in yaml.safe_load(channel.metadata["offered_qos_profiles"])] == [list(PROFILE_KEYS)]
    assert [list(p) for p in _qos_lists(bag)[0]] == [list(PROFILE_KEYS)]
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["custom_data"]["made_by"] == "an old version"  # custom data survives
    again = reindex_bag(bag)
    assert again.rewritten == () and not again.metadata_changed


def test_reindex_cli_no_backup_and_its_errors(tmp_path):
    bag = tmp_path / "old"
    _old_style_bag(bag)
    env_cmd = [sys.executable, "-m", "skillgen_ros.cli.main", "bag", "reindex", "--no-backup", str(bag)]
    out = subprocess.run(env_cmd, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "metadata.yaml rewritten" in out.stdout and not list(bag.glob("*.orig"))
    bad = subprocess.run(env_cmd[:-1] + [str(tmp_path / "nope")], capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "NOT_A_BAG_DIR" in bad.stderr and "Traceback" not in bad.stderr


def test_writer_completes_partial_qos_and_rejects_wrong_values(tmp_path):
    with BagWriter(tmp_path / "b") as w:
        w.add_topic(TopicSpec("/osc_target", "skillgen_interfaces/msg/OscTarget", (OLD_QOS,)))
        w.write("/osc_target", serialize_message(OscTarget()), 5)
    assert [list(p) for p in _qos_lists(tmp_path / "b")[0]] == [list(PROFILE_KEYS)]
    with AnyReader([tmp_path / "b"]) as r:
        assert r.message_count == 1
    for wrong in ({"depth": -1}, {"reliability": "sometimes"}, {"deadline": {"sec": 1}}, {"colour": "red"},
                  {"lifespan": {"sec": -1, "nsec": 0}}):
        with pytest.raises(BagError) as e:
            complete_profile(wrong)
        assert e.value.reason == "BAD_QOS", wrong
    with BagWriter(tmp_path / "c") as w, pytest.raises(BagError) as e:
        w.add_topic(TopicSpec("/x", "skillgen_interfaces/msg/OscTarget", ({"depth": "ten"},)))
    assert e.value.reason == "BAD_QOS"


def test_shipped_bag_copy_reindexes_as_already_complete(tmp_path):
    copy = tmp_path / "demo"
    shutil.copytree(SHIPPED[0], copy)
    before = {p.name: p.read_bytes() for p in copy.iterdir()}
    r = reindex_bag(copy)
    assert r.rewritten == () and not r.metadata_changed
    assert {p.name: p.read_bytes() for p in copy.iterdir()} == before

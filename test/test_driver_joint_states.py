"""The driver's object_joint_states topic (nodes/driver_joints.py) through a running sim_driver: Coffee's
lid angle after a reset, then while a hand streamed as osc_target pushes the lid shut, and the same values
period by period in its state_history (what graph datasets record); a scene without articulated objects
publishes no names."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skillgen_ros import rosenv  # noqa: F401

from sensor_msgs.msg import JointState
from skillgen_interfaces.srv import StateHistory, TaskSuccess
from skillgen_ros.core.tasks import coffee as C
from skillgen_ros.nodes.convert import pose_from_msg
from skillgen_ros.nodes.driver_joints import QOS, TOPIC
from skillgen_ros.nodes.state_history import ns, to_time
from test_driver_interface import Client, client  # noqa: F401  (fixture)

LID = "coffee_machine/lid"


def _lid(c: Client) -> float:
    m = c.last["joints"]
    return dict(zip(m.name, m.position))[LID]


def test_lid_angle_on_the_topic_follows_the_pushed_lid(start_node, client):  # noqa: F811
    c = client
    c.node.create_subscription(JointState, TOPIC, lambda m: c.last.__setitem__("joints", m), QOS)
    start_node("sim_driver", "--ros-args", "-p", "camera_hz:=0.0", "-p", "lockstep_timeout_s:=30.0")
    res = c.reset("Coffee", "D0", 0)
    assert res.success, res.message
    assert c.spin_until(lambda: "joints" in c.last and LID in c.last["joints"].name and "gt" in c.last
                        and c.last["gt"].header.stamp == c.last["joints"].header.stamp)
    assert list(c.last["joints"].name) == [LID]
    assert _lid(c) == pytest.approx(2 * np.pi / 3)     # open at 120 deg after the reset
    m = next(pose_from_msg(o.pose) for o in c.last["gt"].objects if o.id == "coffee_machine")
    at = lambda local: m.rotation.apply(local) + m.position  # noqa: E731 -- machine frame -> world
    quat = (m.rotation * Rotation.from_euler("z", np.pi / 2) * Rotation.from_euler("x", np.pi)).as_quat()
    assert c.spin_until(lambda: "ee_pose" in c.last)
    start = pose_from_msg(c.last["ee_pose"].pose).position
    path = [start + (at([0.0, -0.03, 0.24]) - start) * k / 40 for k in range(1, 41)]
    path += [at([0.0, -0.03, 0.24 - 0.08 * k / 20]) for k in range(1, 21)]
    path += [at([0.0, -0.03 + 0.14 * k / 40, 0.16]) for k in range(41)]
    path += [at([0.0, 0.11, 0.16 + 0.1 * k / 20]) for k in range(1, 21)] + [at([0.0, 0.11, 0.26])] * 20
    seen, stamps = [], []
    for xyz in path:   # lockstep: one period per target; wait for that period's joint values
        stamp = c.last["joints"].header.stamp
        c.target(xyz, quat, gripper=1.0)
        assert c.spin_until(lambda: c.last["joints"].header.stamp != stamp, 10.0)
        seen.append(_lid(c))
        stamps.append(ns(c.last["joints"].header.stamp))
    assert seen[0] == pytest.approx(2 * np.pi / 3, abs=1e-6)
    assert seen[-1] < C.LID_CLOSED_TOLERANCE           # pushed over upright, it fell shut
    assert not c.call(c.success_cli, TaskSuccess.Request()).success   # the pod is still on the table
    history = c.node.create_client(StateHistory, "state_history")
    hist = c.call(history, StateHistory.Request(after=to_time(stamps[0] - 1)))
    assert hist.success and list(hist.joint_names) == [LID], hist.message
    by_stamp = dict(zip(map(ns, hist.stamps), hist.object_joints))
    assert len(hist.object_joints) == len(hist.stamps) and [by_stamp[t] for t in stamps] == seen  # bit for bit
    # a scene without articulated objects: the latched message names nothing
    assert c.reset("Square", "D0", 0).success
    assert c.spin_until(lambda: len(c.last["joints"].name) == 0)
    square = c.call(history, StateHistory.Request(after=to_time(ns(c.last["joints"].header.stamp) - 1)))
    assert square.success and len(square.stamps) >= 1 and not square.joint_names and not square.object_joints

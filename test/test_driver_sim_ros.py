"""sim_driver over ROS 2: the scripted solution driven through osc_target topics in lockstep reaches
task success; realtime mode advances on the wall clock; lockstep advances after its timeout."""
from __future__ import annotations

import time

import numpy as np
import pytest

from skillgen_ros import rosenv  # noqa: F401

from skillgen_interfaces.msg import OscTarget
from skillgen_interfaces.srv import TaskSuccess
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.tasks import get_task, scripted
from skillgen_ros.nodes.convert import pose_from_msg, pose_to_msg, wrench_from_msg
from test_driver_interface import Client, client  # noqa: F401  (fixture)

# parameters come from the node's defaults (same values as params/sim_driver.yaml) plus -p overrides:
# a --params-file given after -p would override them.


class RosEnv:
    """The scripted solver's env protocol over the driver's topics (ground truth for object poses)."""

    control_hz = 20.0

    def __init__(self, c: Client, task: str, variant: str, seed: int):
        self.c = c
        res = c.reset(task, variant, seed)
        assert res.success, res.message
        spec = get_task(task)
        self.scene = type("Scene", (), {"task": task, "objects": spec.objects_for(variant)})()
        assert c.spin_until(lambda: "gt" in c.last and "ee_pose" in c.last)
        self.n_ee = 0
        self.wrenches: list = []  # (gripper command, ee_wrench, EE z) per step
        c.node.create_subscription(type(c.last["ee_pose"]), "ee_pose", self._count, 10)

    def _count(self, _m):
        self.n_ee += 1

    def ee_pose(self) -> Pose:
        return pose_from_msg(self.c.last["ee_pose"].pose)

    def object_poses(self) -> dict:
        return {o.id: pose_from_msg(o.pose) for o in self.c.last["gt"].objects}

    def step(self, pose: Pose, gripper: float) -> None:
        n = self.n_ee
        self.c.pub.publish(OscTarget(pose=pose_to_msg(pose), gripper=float(gripper)))
        # the period's ee_pose, its ground truth and its ee_wrench (same stamp) must all have arrived
        # (on a loaded machine the first ee_wrench can come after the first ee_pose: wait, do not index it)
        assert self.c.spin_until(lambda: self.n_ee > n and "ee_wrench" in self.c.last and self.c.last["gt"].header.stamp
                                 == self.c.last["ee_pose"].header.stamp == self.c.last["ee_wrench"].header.stamp,
                                 10.0)
        self.wrenches.append((float(gripper), wrench_from_msg(self.c.last["ee_wrench"]),
                              pose_from_msg(self.c.last["ee_pose"].pose).position[2]))

    def task_success(self) -> bool:
        return self.c.call(self.c.success_cli, TaskSuccess.Request()).success


def test_scripted_solution_over_ros_lockstep(start_node, client):  # noqa: F811
    start_node("sim_driver", "--ros-args", "-p", "camera_hz:=0.0", "-p", "lockstep_timeout_s:=30.0")
    assert client.reset_cli.wait_for_service(timeout_sec=20.0)
    env = RosEnv(client, "PickPlace", "D0", 0)
    assert not env.task_success()
    result = scripted.solve(env)
    assert result.success
    # ee_wrench: nothing on the hand while it moves open through free space; carrying the object
    # clear of the table, the hand holds up its weight (a downward force)
    free = [w for g, w, z in env.wrenches if g < 0 and z > 0.2]
    carrying = [w for g, w, z in env.wrenches if g > 0 and z > 0.15]
    assert free and carrying
    assert max(np.linalg.norm(w[:3]) for w in free) < 1e-6
    mass = next(o.mass for o in get_task("PickPlace").objects_for("D0") if o.mass > 0)
    assert np.median([w[2] for w in carrying]) == pytest.approx(-9.81 * mass, rel=0.5)


def test_lockstep_timeout_and_realtime_clock(start_node, client):  # noqa: F811
    # lockstep: no commands -> after each lockstep_timeout_s one period advances anyway. Counted, not
    # timed (the rate against the wall clock is bench/timing/run.py's): the sim clock keeps advancing
    # with nobody commanding, one 0.05 s period at a time.
    proc = start_node("sim_driver", "--ros-args", "-p", "camera_hz:=0.0", "-p", "lockstep_timeout_s:=0.25")
    assert client.spin_until(lambda: "/clock" in client.last, 20.0)
    ticks = []
    client.node.create_subscription(type(client.last["/clock"]), "/clock",
                                    lambda m: ticks.append(m.clock.sec * 10**9 + m.clock.nanosec), 50)
    assert client.spin_until(lambda: len(ticks) >= 4, 60.0), ticks
    steps = np.diff(ticks)
    assert np.all(steps > 0) and np.all(steps % 50_000_000 == 0), steps  # whole periods, forwards
    proc.stop()


def test_realtime_mode_follows_wall_clock(start_node, client):  # noqa: F811
    start_node("sim_driver", "--ros-args", "-p", "timing_mode:=realtime", "-p", "camera_hz:=0.0",
               "-p", "initial_task:=Square")
    assert client.spin_until(lambda: "ee_pose" in client.last, 20.0)
    stamps = []
    client.node.create_subscription(type(client.last["ee_pose"]), "ee_pose",
                                    lambda m: stamps.append(m.header.stamp.sec + m.header.stamp.nanosec * 1e-9), 50)
    # periods come without commands, stamped by the wall clock (their rate: bench/timing/run.py)
    assert client.spin_until(lambda: len(stamps) >= 10, 60.0)
    assert np.all(np.diff(stamps) > 0) and abs(stamps[-1] - time.time()) < 60.0
    ee0 = client.ee()
    goal = ee0 + np.array([0.05, 0.05, -0.05])

    def streamed_and_arrived() -> bool:  # stream the target, as a real client would, until it arrives
        client.target(goal)
        return bool(np.linalg.norm(client.ee() - goal) < 0.01)
    assert client.spin_until(streamed_and_arrived, 60.0), client.ee() - goal

"""RosGraphEnv's observations carry the sim driver's ee_wrench of the same control period: zero in
free space, the peg pushing up once the hand presses on it (what the release's clear steers by)."""
import numpy as np
import pytest

from conftest import wait_for


@pytest.fixture
def env(sim_driver, ros_node):
    from skillgen_ros.nodes.datagen import TIMEOUTS
    from skillgen_ros.nodes.graph_env import RosGraphEnv

    e = RosGraphEnv(ros_node, TIMEOUTS)
    assert wait_for(lambda: e.reset_cli.service_is_ready(), 30.0)
    return e


@pytest.mark.sim_driver(camera_hz=0.0, cameras=[""])
def test_observations_carry_the_periods_wrench(env):
    from skillgen_ros.core.geometry import Pose

    env.reset("Square", "D0", 0)
    obs = env.observe()
    assert obs.ee_wrench is not None
    np.testing.assert_array_equal(obs.ee_wrench, np.zeros(6))
    peg = next(o for o in env.scene_objects if o.id == "square_peg")
    assert peg.has_pose
    top = Pose.from_array(obs.ee_pose)
    xy = [peg.pose.position.x, peg.pose.position.y]
    from skillgen_ros.core.tasks import get_task

    peg_top = peg.pose.position.z + get_task("Square").object("square_peg").half_extents[2]
    for z in (peg_top + 0.1, peg_top - 0.03):  # above the peg, then pressing 3 cm into its top
        for _ in range(25):
            obs = env.step(Pose([*xy, z], top.quaternion), 1.0)
    assert obs.ee_wrench[2] > 5.0  # the peg pushes the hand up
    assert np.linalg.norm(obs.ee_wrench[:2]) < obs.ee_wrench[2]

"""RosGraphEnv's robot state after a replayed skill: the joint_states reader is not spun while skill_replay
runs the driver, and could hold a period from early in the skill. The state then comes from state_history's
newest period, and an older joint_states message does not replace it (it did: observations and the next
plan's start were the stale state, and the trajectory dragged the arm back to it)."""
import numpy as np

from skillgen_ros.core.robot import ARM_JOINTS, FINGER_JOINTS


class _History:
    """state_history's answer: two periods after the skill's last step, the newest last but not first."""

    def __init__(self):
        self.asked = []

    def periods(self, after_ns: int, until_ns: int = 0) -> dict:
        self.asked.append(after_ns)
        return {"stamps": [5_000, 4_000], "q": np.array([np.full(7, 0.2), np.full(7, 0.1)]),
                "fingers": np.array([[0.03, 0.03], [0.01, 0.01]])}


def _joints(q, stamp_ns):
    from skillgen_ros.nodes import convert
    from skillgen_ros.nodes.state_history import to_time

    return convert.joint_state(ARM_JOINTS + FINGER_JOINTS, np.r_[np.full(7, q), 0.02, 0.02], stamp=to_time(stamp_ns))


def test_the_newest_driver_period_wins_over_a_stale_joint_state(ros_node):
    from skillgen_ros.nodes.datagen import TIMEOUTS
    from skillgen_ros.nodes.graph_env import RosGraphEnv

    env = RosGraphEnv(ros_node, TIMEOUTS)
    assert env._take_joints(_joints(0.0, 1_000))
    env.history = _History()
    env._take_history_state(2_999)                       # after the skill's last step (stamp 3_000)
    assert env.history.asked == [2_999]
    env._take_joints(_joints(0.05, 2_000))               # the reader's period from inside the skill
    obs = env.observe()                                  # (no driver: the reader has nothing newer)
    np.testing.assert_allclose(obs.joint_positions, 0.2)
    np.testing.assert_allclose(obs.gripper, 0.03)
    assert obs.stamp_ns == 5_000
    assert env._take_joints(_joints(0.3, 6_000))         # a newer period is taken
    np.testing.assert_allclose(env.current_q(), 0.3)


def test_newest_robot_state_takes_only_newer_periods_until_a_new_scene():
    from skillgen_ros.nodes.robot_state import NewestRobotState

    s = NewestRobotState()
    assert not s.take_joint_state(None)
    assert s.take_joint_state(_joints(0.1, 2_000))
    s.take_period(np.full(7, 0.2), [0.03, 0.03], 1_500)      # older than what is held: kept out
    np.testing.assert_allclose(s.snapshot()[0], 0.1)
    assert s.take_joint_state(_joints(0.0, 1_000))            # a stale message: accepted, not taken
    assert s.snapshot()[2] == 2_000
    s.new_scene()                                              # a reset's clock may start over
    assert s.take_joint_state(_joints(0.4, 10))
    q, f, stamp = s.snapshot()
    np.testing.assert_allclose(q, 0.4)
    np.testing.assert_allclose(f, 0.02)
    assert stamp == 10

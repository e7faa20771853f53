"""Articulated objects in the pybullet world (core/sim/articulation.py): Coffee's lid hinge under real
physics and the torque OSC, its value read back, a state round trip, and the holder seating a pod."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.robot import Q_HOME
from skillgen_ros.core.sim import SimWorld
from skillgen_ros.core.tasks import coffee as C

LID = "coffee_machine/lid"


@pytest.fixture(scope="module")
def world():
    w = SimWorld()
    yield w
    w.close()


def _move(world, target: np.ndarray, quat, periods: int) -> None:
    start = world.ee_pose().position
    for k in range(1, periods + 1):
        world.step(Pose(start + (target - start) * k / periods, quat), 1.0)


def test_reset_opens_the_lid_and_a_scripted_hand_pushes_it_shut(world):
    scene = world.reset("Coffee", "D0", 0)
    assert scene.object_joints == pytest.approx({LID: 2 * np.pi / 3})      # coffee.py _reset_internal
    assert world.scene_state().joints == pytest.approx({LID: 2 * np.pi / 3})
    assert not world.task_success()
    m = scene.poses["coffee_machine"]
    at = lambda local: m.rotation.apply(local) + m.position  # noqa: E731 -- machine frame -> world
    down = (m.rotation * Rotation.from_euler("z", np.pi / 2) * Rotation.from_euler("x", np.pi)).as_quat()
    # closed fingers 5 cm above the hinge, behind the open lid (machine -y), then along machine +y past the hinge
    _move(world, at([0.0, -0.03, 0.24]), down, 40)
    _move(world, at([0.0, -0.03, 0.16]), down, 20)
    assert world.object_joints()[LID] == pytest.approx(2 * np.pi / 3, abs=1e-6)   # untouched so far
    seen = []
    for k in range(41):
        world.step(Pose(at([0.0, -0.03 + 0.14 * k / 40, 0.16]), down), 1.0)
        seen.append(world.object_joints()[LID])
    _move(world, at([0.0, 0.11, 0.26]), down, 20)
    world.idle(20)
    lid = world.object_joints()[LID]
    assert min(seen) < np.radians(90.0) < seen[0]          # the hand tipped it over upright ...
    assert lid < C.LID_CLOSED_TOLERANCE and lid >= -1e-3   # ... and it fell shut on its limit
    assert world.scene_state().joints[LID] == lid
    # the joint is part of the saved state
    s = world.get_state()
    world.show_state(Q_HOME, {}, {LID: 1.0})
    assert world.object_joints()[LID] == pytest.approx(1.0)
    world.set_state(s)
    assert world.object_joints()[LID] == pytest.approx(lid)
    np.testing.assert_allclose(world.get_state(), s, atol=1e-9)


def test_friction_holds_the_lid_near_upright_and_gravity_shuts_it_from_low(world):
    world.reset("Coffee", "D1", 4)
    world.show_state(Q_HOME, {}, {LID: np.radians(95.0)})
    world.idle(20)
    assert np.degrees(world.object_joints()[LID]) == pytest.approx(95.0, abs=0.5)
    world.show_state(Q_HOME, {}, {LID: np.radians(45.0)})
    world.idle(20)
    assert abs(world.object_joints()[LID]) < np.radians(1.0)
    world.show_state(Q_HOME, {}, {LID: np.radians(119.0)})   # past upright: it falls open onto the 120 deg limit
    world.idle(20)
    assert world.object_joints()[LID] == pytest.approx(2 * np.pi / 3, abs=np.radians(0.5))


def test_every_part_of_the_machine_collides(world):
    """pybullet keeps 16 children per compound: the 70 parts ride on the base and static links."""
    scene = world.reset("Coffee", "D0", 0)
    m = next(o for o in scene.objects if o.id == "coffee_machine")
    body, p = world.bodies["coffee_machine"], world.p
    n = sum(len(p.getCollisionShapeData(body, k)) for k in range(-1, p.getNumJoints(body)))
    assert n == len(m.parts) + len(m.links[0].parts) == 71


def test_a_pod_dropped_into_the_holder_seats_and_the_task_succeeds(world):
    scene = world.reset("Coffee", "D0", 0)
    m = scene.poses["coffee_machine"]
    seat = C.HOLDER_POS + [0.0, 0.0, -C.HOLDER_HALF_H + 2 * C.HOLDER_BASE_HALF_H + C.HOLDER_BASE_OFFSET
                           + C.POD_HALF[2] + 0.002]
    world.show_state(Q_HOME, {"coffee_pod": Pose(m.rotation.apply(seat) + m.position, m.quaternion)})
    world.idle(10)
    assert not world.task_success()          # the lid is open
    world.show_state(Q_HOME, {}, {LID: 0.0})
    world.idle(20)
    pod = world.object_poses()["coffee_pod"].position
    holder = m.rotation.apply(C.HOLDER_POS) + m.position
    assert np.linalg.norm(pod[:2] - holder[:2]) < 0.002
    assert world.task_success()

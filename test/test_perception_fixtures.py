"""An object inside an articulated fixture (core/perception/fixtures.py): Coffee Prep's pod in the opened
drawer, on the 128 x 128 front camera generation uses (sim_env / params/sim_driver.yaml)."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pybullet")

from scipy.spatial.transform import Rotation  # noqa: E402

from skillgen_ros.core.geometry import Pose  # noqa: E402
from skillgen_ros.core.perception import cloud  # noqa: E402
from skillgen_ros.core.perception.fixtures import SceneFixtures, estimate_with_fixtures  # noqa: E402
from skillgen_ros.core.perception.models import box_model, models_for_objects  # noqa: E402
from skillgen_ros.core.perception.pipeline import (EstimatedPose, PerceptionStatus, _compatible,  # noqa: E402
                                                   estimate_poses)
from skillgen_ros.core.robot import Q_HOME  # noqa: E402
from skillgen_ros.core.sim import SimWorld  # noqa: E402
from skillgen_ros.core.sim.camera import CameraConfig  # noqa: E402
from skillgen_ros.core.tasks import get_task  # noqa: E402

OPEN = -0.2  # m: the drawer's slide 20 cm out (MimicGen's drawer_open subtask ends below -0.19)


@pytest.fixture(scope="module")
def world():
    w = SimWorld(cameras=(CameraConfig("front", 128, 128, noise_base=0.001),))
    yield w
    w.close()


def _drawer_open(world, seed: int) -> dict[str, Pose]:
    """Coffee Prep D0 with the drawer 20 cm out and the pod carried with it (shown kinematically)."""
    world.reset("CoffeePreparation", "D0", seed)
    poses = dict(world.object_poses())
    out = Rotation.from_quat(poses["drawer"].quaternion).apply([0.0, OPEN, 0.0])  # the slide is the drawer's y
    poses["coffee_pod"] = Pose(poses["coffee_pod"].position + out, poses["coffee_pod"].quaternion)
    world.show_state(np.r_[Q_HOME, 0.04, 0.04], poses, {"drawer/slide": OPEN})
    return poses


@pytest.mark.parametrize("seed", [0, 1])
def test_the_pod_in_the_opened_drawer_is_found_without_the_drawers_points(world, seed):
    spec = get_task("CoffeePreparation")
    models, specs = models_for_objects(spec.objects), {o.id: o for o in spec.objects}
    world.reset("CoffeePreparation", "D0", seed)   # the reset's look: the drawer shut, the pod hidden in it
    frame = world.render("front")
    before = estimate_poses(frame.valid_points(), models, camera_position=frame.T_world_camera[:3, 3],
                            object_ids=["drawer", "coffee_machine", "mug"])
    assert before.ok, before.message
    known = {i: e.pose for i, e in before.poses.items()}
    truth = _drawer_open(world, seed)
    frame = world.render("front")
    pts, cam = frame.valid_points(), frame.T_world_camera[:3, 3]
    alone = estimate_poses(pts, models, camera_position=cam)
    # the opened drawer matches its (shut) model no more, and the pod's points join its tray
    assert alone.status is PerceptionStatus.OBJECT_MISSING and {"drawer", "coffee_pod"}.isdisjoint(alone.poses)
    res = estimate_with_fixtures(pts, models, specs, camera_position=cam, joints=world.object_joints(), known=known)
    assert np.linalg.norm(res.poses["coffee_pod"].pose.position - truth["coffee_pod"].position) < 0.005
    assert res.status is PerceptionStatus.OBJECT_MISSING and "drawer" not in res.poses   # not seen now: said so
    assert "drawer" in res.message and "coffee_pod" not in res.message.split("(")[0]
    assert res.poses["coffee_machine"].pose.position == pytest.approx(alone.poses["coffee_machine"].pose.position)
    assert np.linalg.norm(res.poses["mug"].pose.position - truth["mug"].position) < 0.005  # looked for again
    # without the joint values the drawer's links are where a reset leaves them (shut): the tray stays
    shut = estimate_with_fixtures(pts, models, specs, camera_position=cam, joints=None, known=known)
    assert "coffee_pod" not in shut.poses and "coffee_pod" in shut.message
    # nor without the drawer's earlier pose
    assert "coffee_pod" not in estimate_with_fixtures(pts, models, specs, camera_position=cam,
                                                      joints=world.object_joints()).poses


def test_a_scene_without_articulated_fixtures_is_the_first_look(world):
    spec = get_task("Square")
    world.reset("Square", "D1", 2)
    frame = world.render("front")
    models = models_for_objects(spec.objects)
    a = estimate_poses(frame.valid_points(), models, camera_position=frame.T_world_camera[:3, 3])
    b = estimate_with_fixtures(frame.valid_points(), models, {o.id: o for o in spec.objects},
                               camera_position=frame.T_world_camera[:3, 3])
    assert a.status == b.status and set(a.poses) == set(b.poses)
    assert all(np.allclose(a.poses[k].pose.matrix(), b.poses[k].pose.matrix()) for k in a.poses)


def test_the_size_gate_of_a_cluster_off_the_table():
    """A cluster resting on something above the table (a drawer's tray) is gated on its own height; one
    that reaches the table on its top's height above the table, as before."""
    plane = cloud.Plane(np.array([0.0, 0.0, 1.0]), 0.0, 1000, 0.001)
    model = box_model("pod", (0.024, 0.024, 0.023))   # 4.6 cm tall
    g = np.stack(np.meshgrid(np.linspace(-0.02, 0.02, 5), np.linspace(-0.02, 0.02, 5), np.linspace(0, 0.04, 5)),
                 -1).reshape(-1, 3)
    assert _compatible(g + [0.5, 0.0, 0.0], plane, model, 0.02)            # on the table
    assert _compatible(g + [0.5, 0.0, 0.08], plane, model, 0.02)           # on a tray 8 cm up
    assert not _compatible(g * [1, 1, 3] + [0.5, 0.0, 0.08], plane, model, 0.02)  # 12 cm tall: not the pod
    assert _compatible(g + [0.5, 0.0, 0.01], plane, model, 0.02)           # 1 cm up: gated as on the table
    reaching = np.vstack([g + [0.5, 0.0, 0.08], [[0.5, 0.0, 0.0]]])       # joined to the table: 12 cm above it
    assert not _compatible(reaching, plane, model, 0.02)


def test_a_pod_fitted_to_the_machines_holder_is_looked_for_again(world):
    """The lid open, the mug in the holder: the machine matches its model no more, and the first look fits the
    pod's model to the machine's cup-shaped holder; without the machine's points the pod is where it lies."""
    spec = get_task("CoffeePreparation")
    models, specs = models_for_objects(spec.objects), {o.id: o for o in spec.objects}
    world.reset("CoffeePreparation", "D0", 0)
    frame = world.render("front")
    known = {i: e.pose for i, e in estimate_poses(frame.valid_points(), models,
                                                  camera_position=frame.T_world_camera[:3, 3],
                                                  object_ids=["drawer", "coffee_machine"]).poses.items()}
    truth = _drawer_open(world, 0)
    m = truth["coffee_machine"]
    holder = m.position + Rotation.from_quat(m.quaternion).apply(spec.object("coffee_machine").keypoint("pod_holder"))
    truth["mug"] = Pose([holder[0], holder[1], truth["mug"].position[2]], truth["mug"].quaternion)  # under the holder
    world.show_state(np.r_[Q_HOME, 0.04, 0.04], truth, {"drawer/slide": OPEN, "coffee_machine/lid": 1.74})
    frame = world.render("front")
    pts, cam = frame.valid_points(), frame.T_world_camera[:3, 3]
    res = estimate_with_fixtures(pts, models, specs, camera_position=cam, joints=world.object_joints(), known=known)
    assert np.linalg.norm(res.poses["coffee_pod"].pose.position - truth["coffee_pod"].position) < 0.005
    first = estimate_poses(pts, models, camera_position=cam)
    assert np.linalg.norm(first.poses["coffee_pod"].pose.position - truth["coffee_pod"].position) > 0.1  # the holder


def test_fixture_poses_are_kept_per_scene():
    """The graph's perception node keeps what it saw of the fixtures between looks; a D1/D2 reset moves
    them, so a look in the next scene must not lend it the last scene's drawer (its removal boxes would
    sit where the drawer was)."""
    from types import SimpleNamespace

    specs = {o.id: o for o in get_task("CoffeePreparation").objects}

    def seen(x):  # a look's result: the drawer at x, and a mug
        return SimpleNamespace(poses={"drawer": EstimatedPose(Pose([x, -0.35, 0.0], [0, 0, 0, 1]), 1.0, "drawer"),
                                      "mug": EstimatedPose(Pose([0.5, 0.1, 0.0], [0, 0, 0, 1]), 1.0, "mug")})

    mem = SceneFixtures()
    assert mem.known((10, 0)) == {}
    mem.update((10, 0), seen(0.71), specs)
    assert set(mem.known((10, 0))) == {"drawer"}  # fixtures only: a mug moves
    assert mem.known((52, 300)) == {}  # the next scene starts without the last one's drawer
    mem.update((10, 0), seen(0.80), specs)  # a late answer from the scene before is not this one's
    assert mem.known((52, 300)) == {}
    mem.update((52, 300), seen(0.60), specs)
    assert mem.known((52, 300))["drawer"].position[0] == pytest.approx(0.60)
    assert mem.known(None)["drawer"].position[0] == pytest.approx(0.60)  # no scene named: the memory as it is
    mem.clear()
    assert mem.known(None) == {}

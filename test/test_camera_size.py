"""A sim camera configured 0 x 0 takes the scene's task's size (TaskSpec.camera_size): Threading's 480x360,
which finds the needle at reset where the 128x128 default did not (docs/perception.md: 0/10 scenes)."""
from __future__ import annotations

import pytest

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.perception.fixtures import estimate_with_fixtures
from skillgen_ros.core.perception.models import models_for_objects
from skillgen_ros.core.sim.camera import CameraConfig
from skillgen_ros.core.sim.world import SimWorld
from skillgen_ros.core.tasks import get_task
from skillgen_ros.core.tasks.spec import DEFAULT_CAMERA_SIZE


def test_a_zero_sized_camera_takes_each_scenes_task_size_and_an_explicit_one_stays():
    world = SimWorld(cameras=(CameraConfig("front", 0, 0), CameraConfig("wrist", 96, 72)))
    assert world.render("front").depth.shape == DEFAULT_CAMERA_SIZE[::-1]  # before any reset
    world.reset("Threading", "D0", 0)
    assert get_task("Threading").camera_size == (480, 360)
    assert world.render("front").depth.shape == (360, 480) and world.render("wrist").depth.shape == (72, 96)
    world.reset("Square", "D0", 0)
    assert world.render("front").depth.shape == (128, 128) and world.render("wrist").depth.shape == (72, 96)


def test_a_camera_with_one_zero_side_is_refused():
    with pytest.raises(InvalidInputError) as e:
        SimWorld(cameras=(CameraConfig("front", 0, 128),))
    assert e.value.reason == "INVALID_PARAMETER"


@pytest.mark.parametrize("seed", [5000, 5001, 5002])
def test_threadings_needle_is_found_at_reset_at_the_tasks_size_and_not_at_128(seed):
    """Scenes where 128x128 finds no needle (all of 5000-5009) and 256x256 none of 5000-5005."""
    found = {}
    for size in ((0, 0), (128, 128)):
        world = SimWorld(cameras=(CameraConfig("front", *size, noise_base=0.001),))
        scene = world.reset("Threading", "D0", seed)
        frame = world.render("front")
        res = estimate_with_fixtures(frame.valid_points(), models_for_objects(list(scene.objects)),
                                     {o.id: o for o in scene.objects}, camera_position=frame.T_world_camera[:3, 3],
                                     object_ids=["needle", "tripod"], joints=world.object_joints(), known={})
        found[size] = res.poses.get("needle")
    assert found[(128, 128)] is None
    truth = world.object_poses()["needle"]  # same seed, same reset
    est = found[(0, 0)]
    assert est is not None and float(((est.pose.position - truth.position) ** 2).sum()) ** 0.5 < 0.005

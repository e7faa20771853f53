"""bench/perception: the default-resolution pass renders each task at the sim's default for that task
(TaskSpec.camera_size), so Threading's needle is judged at 480x360 as generation sees it, not at 128x128."""
from __future__ import annotations

import sys

from conftest import REPO

sys.path.insert(0, str(REPO))
from bench.perception import run as perception_bench  # noqa: E402

from skillgen_ros.core.tasks import TASK_NAMES, get_task  # noqa: E402


def test_default_pass_uses_each_tasks_camera_size(monkeypatch):
    from skillgen_ros.core.sim.camera import CameraConfig
    monkeypatch.setattr(perception_bench, "_W", {"cams": {"hi": CameraConfig("front", 640, 480),
                                                          "default": CameraConfig("front", 0, 0)}})
    for task in TASK_NAMES:
        cam = perception_bench._camera("default", task)
        assert (cam.width, cam.height) == tuple(get_task(task).camera_size)
        assert (perception_bench._camera("hi", task).width, perception_bench._camera("hi", task).height) == (640, 480)
    assert (perception_bench._camera("default", "Threading").width,
            perception_bench._camera("default", "Threading").height) == (480, 360)

"""Task suite: object specs and meshes, reset distributions (D0/D1/D2, clutter variants), success, skills.

Pure (no pybullet, no rclpy): the mock driver, perception and the planner import it freely.
"""
from .spec import (MAX_SEED, ObjectSpec, Region, SceneDescription, SceneState, SkillSpec, TaskSpec,  # noqa: F401
                   validate_seed)
from .suite import TASK_NAMES, articulated_object, get_task, regions_markdown, scene_object_spec  # noqa: F401
from ..errors import UnknownTaskError, UnknownVariantError  # noqa: F401

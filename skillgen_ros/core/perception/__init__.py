"""Perception (assumption A3 of the paper): object poses and obstacles from one point cloud.

    estimate_poses(points_world, models, params, camera_position) -> PerceptionResult

Modules: cloud (crop, voxel, RANSAC table, DBSCAN, voxel hulls), models (object models from
meshes, symmetry), pose (hypotheses, ICP refinement, render-free visibility scoring), pipeline
(identity and the whole frame), metrics (ADD, ADD-S, symmetry-aware rotation error), synthetic
(ray-cast test scenes), visibility (self- and scene occlusion without rendering).
Pure: no rclpy, no pybullet.
"""
from .models import ObjectModel, Symmetry, model_for, models_for_objects  # noqa: F401
from .pipeline import (EstimatedPose, PerceptionParams, PerceptionResult, PerceptionStatus,  # noqa: F401
                       estimate_poses)
from .pose import PoseParams  # noqa: F401

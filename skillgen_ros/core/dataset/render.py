"""Re-render a recorded attempt at video resolution, from the dataset arrays.

An attempt's episode holds the measured joint and finger positions and (observation_source
ground_truth, the default with the sim) the true object poses of every step. Placing them in a
fresh pybullet world and rendering the front view gives the attempt as it happened, at 640x480,
after the run: the attempt itself never pays for rendering (the perception camera stays 128x128),
and the clips of the report can be chosen once the failure reasons are known. With
observation_source estimate the objects are shown where the robot believed they were.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..generation.episode import Episode
from ..geometry import Pose
from ..sim import camera as cam
from ..tasks import get_task
from ..tasks.articulation import recorded_joints

VIDEO_SIZE = (640, 480)  # width, height: 480p, what the report's videos play at
CONTROL_HZ = 20.0


@dataclass(frozen=True)
class ClipSpec:
    size: tuple[int, int] = VIDEO_SIZE
    max_frames: int = 60  # longer attempts are sampled sparser (the clip still plays in real time)
    fov_deg: float = 45.0


def frame_stride(steps: int, spec: ClipSpec = ClipSpec()) -> int:
    """Every how many control steps a frame is rendered (at least 2: 10 fps of a 20 Hz attempt)."""
    return max(2, math.ceil(max(steps, 1) / spec.max_frames))


class EpisodeRenderer:
    """One headless pybullet world that re-shows attempts (reset per attempt); close() when done."""

    def __init__(self, spec: ClipSpec = ClipSpec()):
        from ..sim.world import SimWorld  # pybullet: only when a clip is made

        self.spec = spec
        self.world = SimWorld()
        self._cfg = cam.CameraConfig("video", spec.size[0], spec.size[1], fov_deg=spec.fov_deg)
        self._view = cam.view_matrix(cam.front_camera_pose())
        self._proj = cam.projection_matrix(self._cfg)

    def _rgb(self) -> np.ndarray:
        p = self.world.p
        _, _, rgba, _, _ = p.getCameraImage(self._cfg.width, self._cfg.height, viewMatrix=self._view,
                                            projectionMatrix=self._proj, renderer=p.ER_TINY_RENDERER,
                                            flags=p.ER_NO_SEGMENTATION_MASK)
        return np.asarray(rgba, np.uint8).reshape(self._cfg.height, self._cfg.width, 4)[..., :3].copy()

    def render(self, task: str, variant: str, scene_seed: int, episode: Episode) -> tuple[list[np.ndarray], float]:
        """(RGB frames, fps) of one attempt from the front; an attempt that never moved shows its reset scene."""
        self.world.reset(task, variant, scene_seed)
        obs = episode.obs
        steps = len(episode.actions)
        if steps == 0 or "robot0_joint_pos" not in obs or obs["robot0_joint_pos"].shape[1] != 7:
            return [self._rgb()], 1.0
        stride = frame_stride(steps, self.spec)
        objects = get_task(task).objects
        frames = []
        for t in list(range(0, steps, stride)) + ([steps - 1] if (steps - 1) % stride else []):
            q = np.concatenate([obs["robot0_joint_pos"][t], obs["robot0_gripper_qpos"][t]])
            poses = {oid: Pose.from_array(obs[f"{oid}_pose"][t]) for oid in episode.object_ids
                     if f"{oid}_pose" in obs}
            self.world.show_state(q, poses, recorded_joints(objects, obs, t))  # the lid where it was
            frames.append(self._rgb())
        return frames, CONTROL_HZ / stride

    def close(self) -> None:
        self.world.close()

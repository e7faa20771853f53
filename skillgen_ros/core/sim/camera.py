"""RGB-D cameras: pinhole intrinsics, optical-frame poses, pybullet rendering, depth noise, points.

Camera frames are optical frames (REP 103): z forward along the viewing ray, x right, y down in
the image. T_world_camera maps optical-frame coordinates to world coordinates.
"front": fixed, in front of the robot at FRONT_EYE looking at FRONT_TARGET on the table.
"wrist": rigidly on panda_hand at WRIST_IN_HAND (hand frame), optical axis = hand z (toward the
fingers) tilted WRIST_TILT_DEG toward the grasp point; image x = hand y.
Depth noise (optional): z' = z + N(0, (a + b z^2)^2) per pixel, plus dropout (pixels set invalid).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from ..geometry import make_T

FRONT_EYE = np.array([1.35, 0.0, 0.70])
FRONT_TARGET = np.array([0.56, 0.0, -0.07])  # robosuite table centre, 2 cm above its top (core/robot.py)
WRIST_IN_HAND = np.array([0.065, 0.0, 0.03])
WRIST_TILT_DEG = 20.0
GL_FROM_OPTICAL = np.diag([1.0, -1.0, -1.0, 1.0])  # OpenGL camera: y up, looking along -z


@dataclass(frozen=True)
class CameraConfig:
    """width = height = 0: the scene's task decides (TaskSpec.camera_size, resolved by SimWorld.reset)."""

    name: str
    width: int = 128
    height: int = 128
    fov_deg: float = 55.0        # vertical field of view
    near: float = 0.02
    far: float = 3.0
    noise_base: float = 0.0      # a in sigma(z) = a + b z^2 (m)
    noise_quadratic: float = 0.0  # b (1/m)
    dropout: float = 0.0         # probability a pixel has no depth

    def sized(self, size: tuple[int, int]) -> "CameraConfig":
        """This camera at `size` (width, height) if it was configured 0 x 0 (the task's size); else as it is."""
        return replace(self, width=int(size[0]), height=int(size[1])) if self.width == 0 else self

    def intrinsics(self) -> np.ndarray:
        """K in the OpenCV / ROS CameraInfo convention (pixel centres at integer coordinates).

        pybullet's TinyRenderer samples pixel (i, j) on the ray through (w/2 + (i - w/2), ...) with
        rows flipped from OpenGL's bottom-up order, which puts the principal point at
        (w/2, h/2 - 1); measured against the known table plane and box faces (test_sim_world)."""
        f = self.height / (2.0 * np.tan(np.radians(self.fov_deg) / 2.0))
        return np.array([[f, 0.0, self.width / 2.0], [0.0, f, self.height / 2.0 - 1.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class CameraFrame:
    """One RGB-D image. depth: metres along optical z (NaN = no return); points_world: (H, W, 3), NaN invalid."""

    name: str
    rgb: np.ndarray
    depth: np.ndarray
    K: np.ndarray
    T_world_camera: np.ndarray
    points_world: np.ndarray
    segmentation: np.ndarray  # pybullet body id per pixel (-1 background)

    def valid_points(self) -> np.ndarray:
        """(N, 3) finite points in the world frame."""
        p = self.points_world.reshape(-1, 3)
        return p[np.all(np.isfinite(p), axis=1)]


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Optical-frame pose at `eye` looking at `target` with image-up roughly along `up`."""
    z = np.asarray(target, float) - np.asarray(eye, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return make_T(eye, np.stack([x, y, z], axis=1))


def front_camera_pose() -> np.ndarray:
    return look_at(FRONT_EYE, FRONT_TARGET)


def wrist_in_hand() -> np.ndarray:
    """T_hand_camera (optical) for the wrist camera."""
    R = Rotation.from_euler("y", -WRIST_TILT_DEG, degrees=True) * Rotation.from_euler("z", 90, degrees=True)
    return make_T(WRIST_IN_HAND, R.as_matrix())


def projection_matrix(cfg: CameraConfig) -> list[float]:
    """OpenGL projection (column-major, as pybullet expects) matching `cfg.intrinsics()`."""
    n, f = cfg.near, cfg.far
    t = n * np.tan(np.radians(cfg.fov_deg) / 2.0)
    r = t * cfg.width / cfg.height
    P = np.array([[n / r, 0, 0, 0], [0, n / t, 0, 0], [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)], [0, 0, -1, 0]])
    return P.T.reshape(-1).tolist()


def view_matrix(T_world_camera: np.ndarray) -> list[float]:
    V = np.linalg.inv(T_world_camera @ GL_FROM_OPTICAL)
    return V.T.reshape(-1).tolist()


def linearize_depth(zbuf: np.ndarray, near: float, far: float) -> np.ndarray:
    """OpenGL depth buffer [0, 1] -> metric depth along optical z; background (>= 1) -> NaN."""
    z = far * near / (far - (far - near) * zbuf)
    return np.where(zbuf >= 1.0 - 1e-7, np.nan, z)


def add_depth_noise(depth: np.ndarray, cfg: CameraConfig, rng: np.random.Generator) -> np.ndarray:
    if cfg.noise_base <= 0 and cfg.noise_quadratic <= 0 and cfg.dropout <= 0:
        return depth
    sigma = cfg.noise_base + cfg.noise_quadratic * np.nan_to_num(depth) ** 2
    out = depth + rng.standard_normal(depth.shape) * sigma
    if cfg.dropout > 0:
        out = np.where(rng.random(depth.shape) < cfg.dropout, np.nan, out)
    return out


def backproject(depth: np.ndarray, K: np.ndarray, T_world_camera: np.ndarray) -> np.ndarray:
    """Organized (H, W, 3) world points from a depth image (OpenCV pixel convention), NaN where no depth."""
    h, w = depth.shape
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    x = (u - K[0, 2]) * depth / K[0, 0]
    y = (v - K[1, 2]) * depth / K[1, 1]
    pc = np.stack([x, y, depth], axis=-1)
    return pc @ T_world_camera[:3, :3].T + T_world_camera[:3, 3]


def render(client, cfg: CameraConfig, T_world_camera: np.ndarray, rng: np.random.Generator) -> CameraFrame:
    """Render with pybullet's TinyRenderer (headless, deterministic)."""
    _, _, rgba, zbuf, seg = client.getCameraImage(
        cfg.width, cfg.height, viewMatrix=view_matrix(T_world_camera), projectionMatrix=projection_matrix(cfg),
        renderer=client.ER_TINY_RENDERER)
    rgba = np.asarray(rgba, dtype=np.uint8).reshape(cfg.height, cfg.width, 4)
    depth = linearize_depth(np.asarray(zbuf, dtype=np.float64).reshape(cfg.height, cfg.width), cfg.near, cfg.far)
    depth = add_depth_noise(depth, cfg, rng)
    K = cfg.intrinsics()
    seg = np.asarray(seg, dtype=np.int64).reshape(cfg.height, cfg.width)
    seg = np.where(seg < 0, -1, seg & ((1 << 24) - 1))
    return CameraFrame(cfg.name, rgba[..., :3].copy(), depth.astype(np.float32), K, T_world_camera,
                       backproject(depth, K, T_world_camera), seg)

"""A ray-cast depth camera over open3d meshes: synthetic scenes for tests and sanity checks.

Sees only visible surfaces (first ray hit), returns an organized cloud with NaN where a ray hits
nothing, and adds depth noise along the ray, so unit tests exercise the same partial, noisy views
a real or simulated camera produces without needing the simulator.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import open3d as o3d


def posed(mesh: o3d.geometry.TriangleMesh, T: np.ndarray) -> o3d.geometry.TriangleMesh:
    m = o3d.geometry.TriangleMesh(mesh)
    m.transform(np.asarray(T, float))
    return m


def table_mesh(top_z: float = 0.0, size=(1.2, 1.2), center_xy=(0.5, 0.0), thickness=0.05):
    m = o3d.geometry.TriangleMesh.create_box(size[0], size[1], thickness)
    m.translate([center_xy[0] - size[0] / 2, center_xy[1] - size[1] / 2, top_z - thickness])
    return m


def raycast_cloud(meshes: Sequence[o3d.geometry.TriangleMesh], eye, target=(0.5, 0.0, 0.0),
                  width: int = 320, height: int = 240, fov_deg: float = 60.0, noise_std: float = 0.0,
                  up=(0.0, 0.0, 1.0), rng: np.random.Generator | None = None) -> np.ndarray:
    """Organized (H*W, 3) world points seen from `eye` looking at `target`; NaN rows are misses.

    noise_std: standard deviation (m) of Gaussian noise on each ray's depth.
    """
    scene = o3d.t.geometry.RaycastingScene()
    for m in meshes:
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(m))
    rays = o3d.t.geometry.RaycastingScene.create_rays_pinhole(
        fov_deg, list(map(float, target)), list(map(float, eye)), list(map(float, up)), width, height)
    hit = scene.cast_rays(rays)["t_hit"].numpy().reshape(-1)
    r = rays.numpy().reshape(-1, 6)
    d = r[:, 3:] / np.linalg.norm(r[:, 3:], axis=1, keepdims=True)
    t = hit * np.linalg.norm(r[:, 3:], axis=1)
    if noise_std > 0:
        rng = rng or np.random.default_rng(0)
        t = t + rng.normal(0.0, noise_std, size=t.shape)
    pts = r[:, :3] + d * t[:, None]
    pts[~np.isfinite(hit)] = np.nan
    return pts

"""Render-free visibility: which model points a camera sees, and what other things hide.

FoundationPose compares rendered hypotheses with the image; here the same question, "which part of
the model should the camera see at this pose?", is answered on points: a back-face test plus a
point-splat z-buffer per model (self-occlusion, cached per quantized viewpoint), and an occlusion
map of the frame (other objects in front of the model: an obstacle hiding half a nut).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .models import ObjectModel

_UP = np.array([0.0, 0.0, 1.0])


_VIEW_STEP = np.radians(3.0)  # viewpoint quantization of the visibility cache
_VIEW_DIST = 0.05


def visible_mask(model: ObjectModel, T: np.ndarray, camera: np.ndarray | None) -> np.ndarray:
    """Model points the camera would see at pose T, without rendering.

    Visibility depends only on where the camera is in the object's frame; that position is
    quantized (3 degrees of azimuth and elevation, 5 cm of range) and the answer cached per
    model, so after a few frames the test costs a dictionary lookup. Without a camera position
    the view is assumed to come from above (upward-facing normals only).
    """
    R, t = T[:3, :3], T[:3, 3]
    if camera is None:
        return (model.normals @ R.T) @ _UP > 0.0
    c = R.T @ (np.asarray(camera, float) - t)       # camera in the object frame
    dist = float(np.linalg.norm(c))
    az, el = np.arctan2(c[1], c[0]), np.arcsin(np.clip(c[2] / max(dist, 1e-9), -1.0, 1.0))
    key = (int(round(az / _VIEW_STEP)), int(round(el / _VIEW_STEP)), int(round(dist / _VIEW_DIST)))
    return _visible_from(model, key)


@lru_cache(maxsize=20000)
def _visible_from(model: ObjectModel, key: tuple[int, int, int]) -> np.ndarray:
    az, el, dist = key[0] * _VIEW_STEP, key[1] * _VIEW_STEP, max(key[2] * _VIEW_DIST, _VIEW_DIST)
    cam = dist * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return zbuffer_visible(model.points, model.normals, cam)


def zbuffer_visible(points: np.ndarray, normals: np.ndarray, camera: np.ndarray,
                    bin_rad: float = 0.006, depth_tol: float = 0.004) -> np.ndarray:
    """Back-face test (outward normal towards the camera), then a point-splat z-buffer: points
    are binned by viewing direction (`bin_rad` wide, a few times the model's sampling angle) and
    only those within `depth_tol` of the nearest point of their bin survive, which removes
    self-occluded surfaces (a nut's far wall, internal faces of overlapping parts)."""
    v = points - camera
    facing = np.einsum("ij,ij->i", normals, v) < 0.0
    idx = np.flatnonzero(facing)
    if len(idx) == 0:
        return facing
    v = v[idx]
    r = np.linalg.norm(v, axis=1)
    c0 = -camera / np.linalg.norm(camera)            # looking at the object origin
    e1 = np.cross(c0, _UP if abs(c0 @ _UP) < 0.9 else np.array([1.0, 0.0, 0.0]))
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(c0, e1)
    depth = np.maximum(v @ c0, 1e-6)
    ij = np.floor(np.stack([v @ e1, v @ e2], axis=1) / (depth[:, None] * bin_rad)).astype(np.int64)
    key = (ij[:, 0] << 32) + ij[:, 1]
    _, inv = np.unique(key, return_inverse=True)
    zmin = np.full(inv.max() + 1, np.inf)
    np.minimum.at(zmin, inv, r)
    out = np.zeros(len(points), bool)
    out[idx[r <= zmin[inv] + depth_tol]] = True
    out.setflags(write=False)
    return out


class OcclusionMap:
    """Nearest observed range per viewing direction from the camera (tangent-plane bins).

    A model point is occluded when the camera saw something more than `margin` nearer along
    its ray: coverage must not count it as missing data.
    """

    def __init__(self, points: np.ndarray, camera: np.ndarray, bin_rad: float = 0.004):
        self.camera = np.asarray(camera, float)
        v = np.asarray(points, float) - self.camera
        c0 = v.mean(axis=0)
        self.c0 = c0 / np.linalg.norm(c0)
        e1 = np.cross(self.c0, _UP if abs(self.c0 @ _UP) < 0.9 else np.array([1.0, 0.0, 0.0]))
        self.e1 = e1 / np.linalg.norm(e1)
        self.e2 = np.cross(self.c0, self.e1)
        self.bin = bin_rad
        uv, r = self._project(v)
        self.lo = uv.min(axis=0) - 1
        self.shape = (uv.max(axis=0) - self.lo + 2).astype(int)
        self.near = np.full(int(self.shape[0]) * int(self.shape[1]), np.inf)
        np.minimum.at(self.near, self._flat(uv), r)

    def _project(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        depth = np.maximum(v @ self.c0, 1e-6)
        uv = np.floor(np.stack([v @ self.e1, v @ self.e2], axis=1) / (depth[:, None] * self.bin)).astype(np.int64)
        return uv, np.linalg.norm(v, axis=1)

    def _flat(self, uv: np.ndarray) -> np.ndarray:
        return (uv[:, 0] - self.lo[0]) * self.shape[1] + (uv[:, 1] - self.lo[1])

    def occluded(self, points: np.ndarray, margin: float) -> np.ndarray:
        uv, r = self._project(np.asarray(points, float) - self.camera)
        rel = uv - self.lo
        inside = np.all((rel >= 0) & (rel < self.shape), axis=1)
        out = np.zeros(len(points), bool)
        out[inside] = self.near[self._flat(uv[inside])] < r[inside] - margin
        return out

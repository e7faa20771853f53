"""Point-cloud operations of the paper's perception front end: crop, voxel, RANSAC table, DBSCAN.

Everything takes and returns plain (N, 3) float arrays in the world frame, so the same code runs on
a PointCloud2 from a real camera, on a sim render, or on a synthetic test scene. open3d does the
voxel grid (and, in pose.py, the 6-DOF point-to-plane ICP and FPFH registration; the upright ICP
there is ours). The plane RANSAC and DBSCAN are our own, for reasons:
- RANSAC: open3d's `segment_plane` returns the plane with the most inliers, whatever its tilt, so
  a box side or the back wall of a bin can win over the table; ours only considers planes within
  `max_tilt_deg` of up, scores all candidate triples at once on a subsample and refits on the
  whole cloud, seeded, so the same cloud gives the same plane on every machine.
- DBSCAN: the same labelling as open3d's `cluster_dbscan` up to numbering (and border-point ties;
  test_perception compares them), from scipy's KD-tree and connected components, about twice
  as fast on our clouds and without open3d's console progress output.
numpy does the cheap masking.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree


@dataclass(frozen=True)
class Plane:
    """The plane n.x + d = 0 with unit normal n pointing away from the table (up)."""

    normal: np.ndarray
    offset: float
    inliers: int
    noise: float = 0.0  # robust std (m) of the inliers' distances: the depth noise at the table

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        return points @ self.normal + self.offset

    @property
    def point(self) -> np.ndarray:
        """The point of the plane closest to the origin."""
        return -self.offset * self.normal


def finite_points(points: np.ndarray) -> np.ndarray:
    """Drop NaN/inf rows (organized clouds mark missing depth with NaN)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    return pts[np.all(np.isfinite(pts), axis=1)]


def crop(points: np.ndarray, lo, hi) -> np.ndarray:
    """Keep the points inside the axis-aligned workspace box [lo, hi]."""
    lo = np.asarray(lo, float)
    hi = np.asarray(hi, float)
    m = (points[:, 0] >= lo[0]) & (points[:, 0] <= hi[0])  # column-wise: cheaper, and NaN rows fail
    for k in (1, 2):
        m &= (points[:, k] >= lo[k]) & (points[:, k] <= hi[k])
    return points[m]


def to_o3d(points: np.ndarray) -> o3d.geometry.PointCloud:
    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(points, dtype=float)))


def voxel_downsample(points: np.ndarray, voxel: float) -> np.ndarray:
    """One point (the centroid) per occupied voxel; voxel <= 0 leaves the cloud as it is."""
    if voxel <= 0 or len(points) == 0:
        return points
    return np.asarray(to_o3d(points).voxel_down_sample(voxel).points)


def fit_table_plane(points: np.ndarray, distance: float, up=(0.0, 0.0, 1.0), max_tilt_deg: float = 15.0,
                    min_inliers: int = 200, sample: int = 4000, iterations: int = 300,
                    rng: np.random.Generator | None = None) -> Plane | None:
    """RANSAC the dominant plane whose normal is within `max_tilt_deg` of `up`; None if none is found.

    All candidate planes (random point triples) are scored at once on a random subsample (the
    table dominates the view, so a few thousand points find it); planes too tilted to be the table
    (a wall, a box side) are never candidates. Two least-squares refits on the inliers of the whole
    cloud sharpen the winner. Seeded, so the same cloud always gives the same plane.
    """
    rng = rng or np.random.default_rng(0)
    up = np.asarray(up, float) / np.linalg.norm(up)
    if len(points) < max(min_inliers, 3):
        return None
    sub = points if len(points) <= sample else points[rng.choice(len(points), sample, replace=False)]
    tri = sub[rng.integers(0, len(sub), size=(iterations, 3))]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1)
    n = n[norm > 1e-12] / norm[norm > 1e-12, None]
    tri = tri[norm > 1e-12]
    n *= np.sign(n @ up)[:, None]
    level = n @ up >= np.cos(np.radians(max_tilt_deg))
    if not level.any():
        return None
    n, p0 = n[level], tri[level, 0]
    d = -np.einsum("ij,ij->i", n, p0)
    votes = (np.abs(sub @ n.T + d) < distance).sum(axis=0)
    k = int(np.argmax(votes))
    if votes[k] * len(points) / len(sub) < min_inliers:
        return None
    n, d = n[k], float(d[k])
    for _ in range(2):
        sel = np.flatnonzero(np.abs(points @ n + d) < distance)
        if len(sel) < 3:
            return None
        if len(sel) > 20000:
            sel = sel[:: len(sel) // 20000 + 1]
        n, d = _refit(points[sel], n)
    r = points @ n + d
    inl = int((np.abs(r) < distance).sum())
    if inl < min_inliers or n @ up < np.cos(np.radians(max_tilt_deg)):
        return None
    noise = float(1.4826 * np.median(np.abs(r[sel])))
    return Plane(n, d, inl, noise)


def _refit(points: np.ndarray, n0: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares plane through `points` (smallest principal axis), oriented like n0."""
    c = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - c, full_matrices=False)
    n = vt[2]
    if n @ n0 < 0:
        n = -n
    return n, float(-n @ c)


def above_plane(points: np.ndarray, plane: Plane, min_height: float, max_height: float = np.inf) -> np.ndarray:
    """Points strictly above the table (object candidates); table and below-table points go."""
    h = plane.signed_distance(points)
    return points[(h > min_height) & (h < max_height)]


def dbscan_labels(points: np.ndarray, eps: float, min_points: int) -> np.ndarray:
    """DBSCAN (Ester et al. 1996) labels, -1 for noise: a KD-tree finds all eps-neighbour pairs,
    core points (>= min_points neighbours, self included) are linked into connected components,
    and border points join the cluster of a core neighbour. Same labelling as open3d's
    cluster_dbscan up to numbering (and border-point ties), about twice as fast on our clouds.
    """
    n = len(points)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    pairs = cKDTree(points).query_pairs(eps, output_type="ndarray")
    core = np.bincount(pairs.ravel(), minlength=n) + 1 >= min_points
    both = pairs[core[pairs[:, 0]] & core[pairs[:, 1]]]
    graph = coo_matrix((np.ones(len(both)), (both[:, 0], both[:, 1])), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    labels = np.where(core, comp, -1)
    edge = pairs[core[pairs[:, 0]] ^ core[pairs[:, 1]]]
    first_core = core[edge[:, 0]]
    labels[np.where(first_core, edge[:, 1], edge[:, 0])] = comp[np.where(first_core, edge[:, 0], edge[:, 1])]
    # renumber 0..k-1
    used = np.unique(labels[labels >= 0])
    remap = np.full(comp.max() + 1 if n else 1, -1)
    remap[used] = np.arange(len(used))
    return np.where(labels >= 0, remap[np.maximum(labels, 0)], -1)


def dbscan(points: np.ndarray, eps: float, min_points: int) -> list[np.ndarray]:
    """DBSCAN clusters as a list of point arrays, largest first; noise points are dropped."""
    labels = dbscan_labels(points, eps, min_points)
    out = [points[labels == k] for k in range(labels.max() + 1)] if labels.size and labels.max() >= 0 else []
    return sorted(out, key=len, reverse=True)


def point_spacing(points: np.ndarray, sample: int = 500) -> float:
    """Median nearest-neighbour distance (m) of a cloud: its sampling resolution (0 if < 2 points)."""
    if len(points) < 2:
        return 0.0
    idx = np.linspace(0, len(points) - 1, min(sample, len(points))).astype(int)
    d, _ = cKDTree(points).query(points[idx], k=2)
    return float(np.median(d[:, 1]))


def voxel_hull(points: np.ndarray, plane: Plane, voxel: float) -> np.ndarray:
    """Obstacle volume of a cluster seen from above: every occupied voxel column filled to the table.

    A camera sees only the near surface of an unknown object; the planner must not route through
    the unseen part beneath it, so each column is extruded down to the table plane. Returns the
    voxel centres (M, 3); assumes a roughly horizontal table (up = plane normal).
    """
    if len(points) == 0:
        return np.zeros((0, 3))
    n = plane.normal
    h = plane.signed_distance(points)
    foot = points - h[:, None] * n  # projection onto the table
    # An in-plane basis (u, v) so columns are indexed in table coordinates.
    u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    ij = np.floor(np.stack([foot @ u, foot @ v], axis=1) / voxel).astype(np.int64)
    cols, inv = np.unique(ij, axis=0, return_inverse=True)
    top = np.zeros(len(cols))
    np.maximum.at(top, inv.reshape(-1), h)
    out = []
    base = plane.point
    for (i, j), t in zip(cols, top):
        levels = (np.arange(max(int(np.ceil(t / voxel)), 1)) + 0.5) * voxel
        c = base + ((i + 0.5) * voxel) * u + ((j + 0.5) * voxel) * v
        out.append(c + levels[:, None] * n)
    return np.concatenate(out, axis=0)

"""Hidden space: what lies behind an observed surface and no camera saw free is occupied.

A camera sees the fronts of things, not their backs. A cloud turned into obstacles point by point
leaves a box's unseen far side and its edges between two pixel rays free, and plans went through
them (bench/planning: up to ~1 cm deep). MoveIt's occupancy map keeps such cells unknown; here,
like a planner that treats unknown as occupied, they are obstacles.

For each depth view (a depth image with the intrinsics K and the pose it was taken from):
1. shadow sources: pixels whose point is an obstacle (above the table, not the robot itself).
   Rays every half pixel (centres, edge midpoints, corners): inside one smooth surface a ray
   starts on it; at a silhouette or a depth jump it starts at the nearest neighbour's depth, so
   the shadow reaches half a pixel past an edge (the edge lies between two rays);
2. each ray is marched `shadow_px` pixel footprints (at its range) deeper, or to the table: the
   cells it passes are candidates;
3. a candidate is carved (free) if some camera certifies the whole cell in front of what it saw:
   projected into that view, every pixel within the cell's footprint (+`edge_px`) saw a surface
   deeper than the cell by its half-diagonal plus `slope_px` pixel footprints at that range
   (a margin tied to the camera's resolution: a surface seen at a grazing angle changes depth
   by more than a pixel's width from one ray to the next). A pixel without a return certifies
   nothing.
4. refine: a cell left is only partly hidden where it straddles a silhouette or lies just above
   a surface, so its halves that hold a shadow sample are certified the same way (`refine`
   times: 1 cm -> 2.5 mm by default). A whole 1 cm cell, represented by its centre plus the
   cloud margin, kept goals 1-2 cm over a box's far edge out (bench/planning).
Cells left are the hidden space; their centres join the cloud (the cloud margin, >= half a
cell's diagonal, covers each cell).

Space outside every camera's view and space behind the robot itself is not marked (see
docs/planning.md, Known limits).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
from scipy.ndimage import minimum_filter

from ..errors import InvalidInputError

JUMP_PX = 4.0  # neighbouring depths further apart than this many pixel footprints: an edge, not one surface
REFINE = 2  # hidden cells left are halved this often by default (1 cm -> 2.5 mm; bench/planning)
MAX_REFINE = 3  # hidden cells are halved at most this often (1.25 mm from 1 cm: finer than any pixel here)
MAX_FOOTPRINT_PX = 6  # a cell whose footprint is wider than this (very near a camera) is not certified


@dataclass(frozen=True, eq=False)  # identity equality: fields are arrays
class DepthView:
    """One depth image: depth (H,W) along the optical z in metres (NaN = no return), K (3x3,
    OpenCV/ROS CameraInfo convention), T_world_camera (4x4, optical frame -> world)."""

    depth: np.ndarray
    K: np.ndarray
    T_world_camera: np.ndarray

    def __post_init__(self):
        d = np.asarray(self.depth, float)
        K = np.asarray(self.K, float)
        T = np.asarray(self.T_world_camera, float)
        if d.ndim != 2 or K.shape != (3, 3) or T.shape != (4, 4) or not (
                np.all(np.isfinite(K)) and np.all(np.isfinite(T)) and K[0, 0] > 0 and K[1, 1] > 0):
            raise InvalidInputError("depth view: need an (H,W) depth image, a 3x3 K with positive focal "
                                    "lengths and a finite 4x4 camera pose")
        object.__setattr__(self, "depth", np.where(d > 0, d, np.nan))
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "T_world_camera", T)

    @staticmethod
    def from_organized(points_world: np.ndarray, K: np.ndarray, T_world_camera: np.ndarray) -> "DepthView":
        """From an organized world-frame cloud (H,W,3; NaN = no return) and the camera it came from."""
        P = np.asarray(points_world, float)
        if P.ndim != 3 or P.shape[2] != 3:
            raise InvalidInputError(f"depth view: organized cloud must be (H,W,3), got {P.shape}")
        T = np.asarray(T_world_camera, float)
        return DepthView(((P - T[:3, 3]) @ T[:3, :3])[..., 2], K, T)

    def rays(self) -> np.ndarray:
        """(H,W,3) world direction of each pixel's ray, scaled to unit optical z."""
        h, w = self.depth.shape
        return self.rays_at(*np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float)))

    def rays_at(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """World directions (..., 3) of the rays through pixel coordinates (u, v), unit optical z."""
        K = self.K
        r = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
        return r @ self.T_world_camera[:3, :3].T

    def points(self) -> np.ndarray:
        """(H,W,3) world points (NaN where no return)."""
        return self.T_world_camera[:3, 3] + self.rays() * self.depth[..., None]

    def project(self, X: np.ndarray):
        """World points (N,3) -> (column, row) pixel indices (rounded) and optical z."""
        pc = (np.asarray(X, float) - self.T_world_camera[:3, 3]) @ self.T_world_camera[:3, :3]
        z = pc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.rint(self.K[0, 0] * pc[:, 0] / z + self.K[0, 2])
            v = np.rint(self.K[1, 1] * pc[:, 1] / z + self.K[1, 2])
        return u, v, z


def _half_pixel_starts(S: np.ndarray, jump: np.ndarray):
    """Rays every half pixel: at each pixel's centre, edge midpoints and corners. A ray between
    pixels of one smooth surface (all sources, depths within `jump` of each other) starts at
    their mean depth, on the surface; at a silhouette or a depth jump it starts at the nearest
    one, so a surface's shadow reaches half a pixel past its last pixel (its edge lies somewhere
    before the next pixel's centre; the cloud margin covers the other half). Neighbouring rays
    are then closer than a cell. Returns (start, u, v), each (2H+1, 2W+1)."""
    h, w = S.shape
    P = np.full((h + 2, w + 2), np.inf)
    P[1:-1, 1:-1] = S
    J = np.zeros((h + 2, w + 2))
    J[1:-1, 1:-1] = jump

    def pick(blocks, jumps):
        D, Jm = np.stack(blocks), np.stack(jumps).max(axis=0)
        lo, hi = D.min(axis=0), D.max(axis=0)
        with np.errstate(invalid="ignore"):
            smooth = np.isfinite(hi) & (hi - lo <= Jm)
            return np.where(smooth, D.mean(axis=0), lo)

    G = np.full((2 * h + 1, 2 * w + 1), np.inf)
    G[1::2, 1::2] = S
    G[0::2, 1::2] = pick([P[:-1, 1:-1], P[1:, 1:-1]], [J[:-1, 1:-1], J[1:, 1:-1]])  # horizontal edges
    G[1::2, 0::2] = pick([P[1:-1, :-1], P[1:-1, 1:]], [J[1:-1, :-1], J[1:-1, 1:]])  # vertical edges
    G[0::2, 0::2] = pick([P[:-1, :-1], P[1:, :-1], P[:-1, 1:], P[1:, 1:]],
                         [J[:-1, :-1], J[1:, :-1], J[:-1, 1:], J[1:, 1:]])  # corners
    u, v = np.meshgrid(np.arange(2 * w + 1) * 0.5 - 0.5, np.arange(2 * h + 1) * 0.5 - 0.5)
    return G, u, v


def _shadow_samples(view: DepthView, is_robot, floor: float, voxel: float,
                    max_shadow: float, shadow_px: float | None) -> np.ndarray:
    """Points every half cell along the half-pixel rays of obstacle pixels, from the surface depth
    to the table plane, at most max_shadow (and shadow_px pixel footprints + a cell) deep."""
    P = view.points().reshape(-1, 3)
    d = view.depth.reshape(-1)
    src = np.isfinite(d)
    src[src] = P[src, 2] > floor + 0.005
    if np.any(src) and is_robot is not None:
        src[src] = ~is_robot(P[src])
    f = float(max(view.K[0, 0], view.K[1, 1]))
    S = np.where(src, d, np.inf).reshape(view.depth.shape)
    jump = JUMP_PX * np.where(src, d, 0.0).reshape(view.depth.shape) / f
    start, u, v = _half_pixel_starts(S, jump)
    live = np.isfinite(start)
    start, rays = start[live], view.rays_at(u[live], v[live])
    o = view.T_world_camera[:3, 3]
    norm = np.linalg.norm(rays, axis=1)
    depth = np.full(len(start), max_shadow)
    if shadow_px is not None:
        depth = np.minimum(depth, shadow_px * start * norm / f + voxel)
    end = start + depth / norm
    down = rays[:, 2] < 0
    end[down] = np.minimum(end[down], (floor - o[2]) / rays[down, 2])
    step = 0.5 * voxel / norm
    n = np.maximum(0, np.floor((end - start) / step).astype(np.int64) + 1)
    idx = np.repeat(np.arange(len(n)), n)
    k = np.arange(len(idx)) - np.repeat(np.cumsum(n) - n, n)
    t = np.minimum(start[idx] + k * step[idx], end[idx])
    return o + rays[idx] * t[:, None]


def _candidates(samples: np.ndarray, floor: float, voxel: float) -> np.ndarray:
    """Centres of the cells holding a sample."""
    ij = np.floor(samples / voxel).astype(np.int64)
    lo, span = ij.min(axis=0), np.ptp(ij, axis=0) + 1
    key = np.unique(_keys(ij - lo, span))  # 1-D keys: a dense grid of 2.5 mm cells would be ~10^8
    cells = np.column_stack([key // (span[1] * span[2]), key // span[2] % span[1], key % span[2]])
    C = (cells + lo + 0.5) * voxel
    return C[C[:, 2] > floor - 0.5 * voxel]


def _inside(samples: np.ndarray, C: np.ndarray, voxel: float) -> np.ndarray:
    """(N,) True where a sample lies in one of the cells centred at C."""
    cells = np.floor(C / voxel).astype(np.int64)
    lo, span = cells.min(axis=0), np.ptp(cells, axis=0) + 1
    ij = np.floor(samples / voxel).astype(np.int64) - lo
    ok = np.all((ij >= 0) & (ij < span), axis=1)
    ok[ok] = np.isin(_keys(ij[ok], span), _keys(cells - lo, span))
    return ok


def _keys(ij: np.ndarray, span: np.ndarray) -> np.ndarray:
    """One int64 per cell index (N,3) in [0, span)."""
    return (ij[:, 0] * span[1] + ij[:, 1]) * span[2] + ij[:, 2]


def _certified_free(view: DepthView, C: np.ndarray, voxel: float, edge_px: int,
                    slope_px: float) -> np.ndarray:
    """(N,) True where the view saw past the whole cell around each centre (see module doc)."""
    h, w = view.depth.shape
    u, v, z = view.project(C)
    f = float(max(view.K[0, 0], view.K[1, 1]))
    half = 0.5 * np.sqrt(3.0) * voxel
    ok = (z > half) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    free = np.zeros(len(C), bool)
    if not np.any(ok):
        return free
    zi = z[ok]
    foot = np.ceil(half * f / (zi - half)).astype(np.int64) + edge_px
    seen = np.nan_to_num(view.depth, nan=0.0)  # no return: certifies nothing
    need = zi + half + slope_px * zi / f
    res = np.zeros(len(zi), bool)
    ui, vi = u[ok].astype(np.int64), v[ok].astype(np.int64)
    for r in np.unique(foot[foot <= MAX_FOOTPRINT_PX]):
        m = foot == r
        dmin = minimum_filter(seen, size=2 * int(r) + 1, mode="constant", cval=0.0)
        res[m] = need[m] < dmin[vi[m], ui[m]]
    free[ok] = res
    return free


def hidden_space(views: Sequence[DepthView], floor: float,
                 is_robot: Callable[[np.ndarray], np.ndarray] | None = None, voxel: float = 0.01,
                 edge_px: int = 1, slope_px: float = 2.0, max_shadow: float = 1.0,
                 shadow_px: float | None = None, refine: int = REFINE) -> np.ndarray:
    """(M,3) centres of the cells behind observed obstacle surfaces that no view saw free.

    refine: times the cells left are split into 8 and those halves that hold a shadow sample
    certified again; the cells returned are voxel / 2**refine wide.

    floor: the table plane (z); is_robot: (N,3) -> bool for points on the robot itself (they cast
    no shadow: the space behind the arm is the arm's own motion space). shadow_px: how deep the
    shadow behind a surface is, in pixel footprints at its range (+ a cell); None = down to the
    table (every hidden cell; at most max_shadow metres)."""
    if not (isinstance(refine, (int, np.integer)) and 0 <= refine <= MAX_REFINE):
        raise InvalidInputError(f"hidden space: refine must be an integer in [0, {MAX_REFINE}], got {refine!r}")
    samples = [_shadow_samples(v, is_robot, floor, voxel, max_shadow, shadow_px) for v in views]
    samples = np.vstack(samples + [np.empty((0, 3))])
    if not len(samples):
        return np.empty((0, 3))
    C = _candidates(samples, floor, voxel)
    for level in range(refine + 1):
        if level:  # the half-size cells, inside a cell left, that hold a sample
            samples = samples[_inside(samples, C, voxel)] if len(C) else samples[:0]
            if not len(samples):
                return np.empty((0, 3))
            voxel /= 2
            C = _candidates(samples, floor, voxel)
        keep = np.ones(len(C), bool)
        for v in views:
            keep[keep] = ~_certified_free(v, C[keep], voxel, edge_px, slope_px)
        C = C[keep]
    return C

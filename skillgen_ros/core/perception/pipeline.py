"""The perception pipeline of assumption A3: object poses (and obstacles) before the robot moves.

    points (world) -> crop -> RANSAC table -> points above it -> voxel -> DBSCAN clusters
      -> per cluster and candidate model: pose hypotheses, refinement, score (pose.py)
      -> identity by optimal assignment of scene objects to clusters (Hungarian)
      -> unexplained clusters and points -> obstacle cloud / voxel-hull volumes

Bad input is a status, never an exception: an empty or all-NaN cloud, no table, a requested object
that is not seen, more look-alike clusters than objects of that type (two identical objects), or a
cloud in a frame other than the world frame. The status codes match EstimatePoses.srv.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from enum import IntEnum
from typing import Mapping, Sequence

import numpy as np
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..geometry import Pose
from . import cloud
from .models import ObjectModel
from .pose import ClusterFitter, Fit, PoseParams
from .visibility import OcclusionMap


class PerceptionStatus(IntEnum):
    """Same numbers as the constants of skillgen_interfaces/srv/EstimatePoses."""

    OK = 0
    EMPTY_CLOUD = 1
    NO_TABLE = 2
    OBJECT_MISSING = 3
    AMBIGUOUS = 4
    WRONG_FRAME = 5
    NO_DATA = 6
    NO_SCENE = 7
    INTERNAL_ERROR = 8


@dataclass(frozen=True)
class PerceptionParams:
    """Pipeline knobs; metres unless named otherwise. Mirrors params/perception.yaml."""

    world_frame: str = "world"
    workspace_lo: tuple[float, float, float] = (0.2, -0.5, -0.15)   # the table in front of the robot,
    workspace_hi: tuple[float, float, float] = (1.0, 0.5, 0.3)      # below the arm's home pose
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    table_distance: float = 0.004       # RANSAC inlier band of the table plane
    table_max_tilt_deg: float = 15.0
    table_min_points: int = 500
    min_object_height: float = 0.005    # points closer to the table than this are table
    max_object_height: float = 0.5
    voxel: float = 0.0025               # object-cloud voxel size
    dbscan_eps: float = 0.008
    dbscan_min_points: int = 5
    min_cluster_points: int = 30
    group_distance: float = 0.03        # clusters this close may be parts of one object
    size_margin: float = 0.02           # how much bigger than a model a cluster may be and still be tried
    noise_gate: float = 3.0             # scoring gate = noise_gate * table noise, clipped to
    max_inlier_distance: float = 0.01   #   [pose.inlier_distance, max_inlier_distance]
    accept_score: float = 0.35          # fitness * coverage needed to call a cluster an object
    polish_points: int = 1000           # final refinement of each identified object (0: off)
    occlusion: bool = True              # coverage ignores model points hidden behind other things
    remove_known_objects: bool = True   # obstacle cloud without the recognized task objects
    obstacle_volume: bool = True        # voxel-hull volumes instead of raw points for obstacles
    obstacle_voxel: float = 0.01
    obstacle_clearance: float = 0.006   # points this close to a fitted model belong to it
    pose: PoseParams = field(default_factory=PoseParams)


@dataclass(frozen=True)
class EstimatedPose:
    """One recognized object: world pose, 0..1 confidence (fitness * coverage) and its scores."""

    pose: Pose
    confidence: float
    object_type: str
    fitness: float = 0.0
    coverage: float = 0.0
    rmse: float = 0.0


@dataclass(frozen=True)
class PerceptionResult:
    status: PerceptionStatus
    message: str
    poses: dict[str, EstimatedPose]
    obstacles: np.ndarray                      # (M, 3) combined obstacle cloud (world)
    clusters: tuple[np.ndarray, ...] = ()      # every DBSCAN cluster above the table
    unknown_clusters: tuple[np.ndarray, ...] = ()  # clusters matching no requested object
    table: cloud.Plane | None = None
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status is PerceptionStatus.OK


def _fail(status: PerceptionStatus, message: str, timings: dict, table=None) -> PerceptionResult:
    return PerceptionResult(status, message, {}, np.zeros((0, 3)), table=table, timings=timings)


ELEVATED = 0.015  # m: a cluster whose lowest point is this far above the table rests on something else


def _compatible(cluster: np.ndarray, plane: cloud.Plane, model: ObjectModel, margin: float,
                upright: bool = True) -> bool:
    """Cheap size gate: a cluster much wider or taller than the model is not that model
    (upright: against its height and footprint; otherwise against its diameter)."""
    if not upright:
        return float(np.linalg.norm(cluster.max(axis=0) - cluster.min(axis=0))) <= model.diameter + margin
    h = plane.signed_distance(cluster)
    # a cluster off the table (on a shelf or a drawer's tray) is gated on its own height, one that
    # reaches the table on its top's height above it (the part under it may be hidden)
    base = h.min() if h.min() > ELEVATED else 0.0
    if h.max() - base > (model.hi[2] - model.lo[2]) + margin:
        return False
    flat = cluster - np.outer(h, plane.normal)
    ext = flat.max(axis=0) - flat.min(axis=0)
    return float(ext.max()) <= 2 * model.xy_radius + margin


def candidate_groups(clusters: Sequence[np.ndarray], link: float) -> list[frozenset]:
    """Sets of clusters that may be one object: each cluster, each pair closer than `link`, and
    each connected component of that "closer than" graph.

    Thin parts (a needle's shaft, a tripod's post) break an object into several DBSCAN clusters;
    grouping lets one model explain them together, and the size gate keeps groups of separate
    objects from being tried.
    """
    n = len(clusters)
    trees = [cKDTree(c) for c in clusters]
    near = np.zeros((n, n), bool)
    for a in range(n):
        for b in range(a + 1, n):
            d, _ = trees[b].query(clusters[a], distance_upper_bound=link)
            near[a, b] = near[b, a] = bool(np.isfinite(d).any())
    groups = {frozenset([a]) for a in range(n)}
    groups |= {frozenset([a, b]) for a in range(n) for b in range(a + 1, n) if near[a, b]}
    _, comp = connected_components(near, directed=False)
    groups |= {frozenset(np.flatnonzero(comp == k).tolist()) for k in np.unique(comp)}
    return sorted(groups, key=lambda g: (len(g), sorted(g)))


def assign(fits: list[tuple[float, str, frozenset, Fit]], per_object: int = 4) -> dict[str, tuple[frozenset, Fit]]:
    """Exhaustive search (small: a handful of objects, their best few candidates each) for the
    object -> cluster-group assignment with the largest summed score, groups pairwise disjoint.

    Greedy choice fails when two look-alike models (a square and a round peg seen at low
    resolution) each score slightly higher on the other's cluster; the joint optimum does not.
    """
    by_id: dict[str, list] = {}
    for sc, i, g, f in fits:
        if len(by_id.setdefault(i, [])) < per_object:
            by_id[i].append((sc, g, f))
    ids = sorted(by_id, key=lambda i: -by_id[i][0][0])
    best: tuple[float, dict] = (-1.0, {})

    def dfs(k: int, used: frozenset, total: float, pick: dict) -> None:
        nonlocal best
        if total + sum(by_id[i][0][0] for i in ids[k:]) <= best[0]:
            return  # bound: even the best remaining choices cannot win
        if k == len(ids):
            best = (total, dict(pick))
            return
        for sc, g, f in by_id[ids[k]]:
            if not (g & used):
                pick[ids[k]] = (g, f)
                dfs(k + 1, used | g, total + sc, pick)
                del pick[ids[k]]
        dfs(k + 1, used, total, pick)

    dfs(0, frozenset(), 0.0, {})
    return best[1]


FitList = list[tuple[float, str, frozenset, Fit]]


def _occlusion_map(raw: np.ndarray, plane: cloud.Plane, cam, params: PerceptionParams,
                   max_points: int = 40000) -> OcclusionMap | None:
    """Everything the camera saw above the table (the arm included, whatever the crop), thinned."""
    if cam is None or not params.occlusion:
        return None
    pts = raw[plane.signed_distance(raw) > params.min_object_height]  # NaN rows compare False
    if len(pts) == 0:
        return None
    return OcclusionMap(pts[:: max(1, len(pts) // max_points)], cam)


def _fit_groups(clusters, groups, models: Mapping[str, ObjectModel], plane: cloud.Plane, pose_params: PoseParams,
                cam, params: PerceptionParams, occlusion: OcclusionMap | None = None) -> tuple[FitList, dict]:
    """(score, object id, group, fit) for every size-compatible (group, model) pair that scores
    at least accept_score, best first (ids sharing one ObjectModel share its fits), and the
    ClusterFitter of each group."""
    distinct: dict[int, list[str]] = {}
    for i in models:
        distinct.setdefault(id(models[i]), []).append(i)
    fits: FitList = []
    fitters: dict = {}
    for g in groups:
        pts_g = np.concatenate([clusters[c] for c in sorted(g)])
        fitter = None
        for same in distinct.values():
            m = models[same[0]]
            upright_only = pose_params.upright and not pose_params.global_registration
            if not _compatible(pts_g, plane, m, params.size_margin, upright_only):
                continue
            fitter = fitter or ClusterFitter(pts_g, plane.normal, pose_params, cam, seed=min(g),
                                             table_offset=plane.offset, occlusion=occlusion)
            fitters[g] = fitter
            f = fitter.fit(m)
            if f is not None and f.score >= params.accept_score:
                fits += [(f.score, i, g, f) for i in same]
    return sorted(fits, key=lambda x: -x[0]), fitters


def _polish(chosen: dict, fitters: dict, models: Mapping[str, ObjectModel], n_points: int) -> dict:
    """One more refinement of each identified object with (up to) n_points of its cluster: the
    search ran on subsamples, which leaves a little sampling noise in yaw on small faces."""
    out = {}
    for i, (g, f) in chosen.items():
        fitter, m = fitters[g], models[i]
        if not fitter.p.upright or n_points <= 0:
            out[i] = (g, f)
            continue
        T = fitter.refine_upright(m, f.T, fitter.p.fine_iterations, n_points)
        f2 = fitter.score(m, T, n_points, exact=True)
        out[i] = (g, f2 if f2.score >= 0.98 * f.score else f)
    return out


def _identify(fits: FitList, models: Mapping[str, ObjectModel]) -> tuple[dict, set[str]]:
    """Best joint assignment, plus the ids whose identity is ambiguous: a leftover group (no
    cluster of it used) that matches an object's type about as well as that object's own
    cluster is a look-alike (two identical objects), so that type's identities are not trusted."""
    chosen = assign(fits)
    used: set[int] = set().union(*(g for g, _ in chosen.values())) if chosen else set()
    ambiguous: set[str] = set()
    for sc, i, g, f in fits:
        if not (g & used) and (i not in chosen or sc >= 0.8 * chosen[i][1].score):
            ambiguous.update(j for j in models if models[j] is models[i])
    return chosen, ambiguous


def _obstacles(clusters, unknown_clusters, chosen: dict, models: Mapping[str, ObjectModel], plane: cloud.Plane,
               params: PerceptionParams) -> np.ndarray:
    """Every cluster no object explains, plus the known objects (all of their points, or only
    points their fitted model does not explain when remove_known_objects), as voxel-hull
    volumes (obstacle_volume) or raw points."""
    parts = list(unknown_clusters)
    for i, (g, f) in chosen.items():
        pc = np.concatenate([clusters[c] for c in sorted(g)])
        if params.remove_known_objects:
            T = f.T
            d, _ = models[i].tree.query((pc - T[:3, 3]) @ T[:3, :3], distance_upper_bound=params.obstacle_clearance)
            pc = pc[~np.isfinite(d)]
            if len(pc) < params.min_cluster_points:   # nothing unexplained stuck to the object
                continue
        parts.append(pc)
    if params.obstacle_volume:
        parts = [cloud.voxel_hull(p, plane, params.obstacle_voxel) for p in parts]
    return np.concatenate(parts, axis=0) if parts else np.zeros((0, 3))


def estimate_poses(points_world: np.ndarray, models: Mapping[str, ObjectModel],
                   params: PerceptionParams = PerceptionParams(), camera_position=None,
                   object_ids: Sequence[str] | None = None, frame: str | None = None) -> PerceptionResult:
    """Estimate the world pose of every object in `models` (id -> model) seen in the cloud.

    object_ids: the ids that must be found (default all); others are still identified so they
    do not end up in the obstacle cloud. frame: the cloud's frame id, checked against
    params.world_frame. camera_position: the viewpoint for the visibility score.
    """
    t0 = time.perf_counter()
    timings: dict[str, float] = {}

    def lap(name: str, since: float) -> float:
        now = time.perf_counter()
        timings[name] = now - since
        return now

    S = PerceptionStatus
    if frame is not None and frame != params.world_frame:
        return _fail(S.WRONG_FRAME, f"cloud is in frame {frame!r}, expected {params.world_frame!r}", timings)
    wanted = list(models) if not object_ids else list(object_ids)
    unknown = [i for i in wanted if i not in models]
    if unknown:
        return _fail(S.OBJECT_MISSING, f"no model for requested object(s) {unknown}", timings)
    raw = np.asarray(points_world, dtype=float)
    if raw.size == 0:
        return _fail(S.EMPTY_CLOUD, "the cloud has no points", timings)
    if raw.shape[-1] != 3:
        return _fail(S.EMPTY_CLOUD, f"expected (N, 3) points, got shape {raw.shape}", timings)
    raw = raw.reshape(-1, 3)
    pts = cloud.crop(raw, params.workspace_lo, params.workspace_hi)  # NaN rows fail the box test
    if len(pts) == 0:
        if not np.isfinite(raw).all(axis=1).any():
            return _fail(S.EMPTY_CLOUD, f"all {len(raw)} points are NaN/inf", timings)
        return _fail(S.EMPTY_CLOUD, "no points inside the workspace box", timings)
    t = lap("crop", t0)

    plane = cloud.fit_table_plane(pts, params.table_distance, params.up, params.table_max_tilt_deg,
                                  params.table_min_points)
    if plane is None:
        return _fail(S.NO_TABLE, "no table plane found in view", timings)
    above = cloud.above_plane(pts, plane, params.min_object_height, params.max_object_height)
    above = cloud.voxel_downsample(above, params.voxel)
    t = lap("table", t)

    # Low-resolution cameras sample objects sparsely: neighbourhoods and gates grow with the
    # measured point spacing, cluster-size limits shrink with it (the configured values hold at
    # or below voxel-size spacing).
    spacing = cloud.point_spacing(above)
    sparse = max(spacing / params.voxel, 1.0) if spacing > 0 else 1.0
    eps = max(params.dbscan_eps, 2.0 * spacing)
    min_pts = max(8, int(params.min_cluster_points / sparse**2))
    clusters = [c for c in cloud.dbscan(above, eps, params.dbscan_min_points if sparse < 2 else 3)
                if len(c) >= min_pts]
    t = lap("cluster", t)

    cam = None if camera_position is None else np.asarray(camera_position, float)
    occlusion = _occlusion_map(raw, plane, cam, params)
    # Scoring gate follows the depth noise measured on the table (never tighter than configured).
    tau = float(np.clip(max(params.noise_gate * plane.noise, 0.75 * spacing),
                        params.pose.inlier_distance, params.max_inlier_distance))
    groups = candidate_groups(clusters, max(params.group_distance, 3.0 * spacing))
    fits, fitters = _fit_groups(clusters, groups, models, plane, replace(params.pose, inlier_distance=tau), cam,
                                params, occlusion)
    chosen, ambiguous = _identify(fits, models)
    chosen = _polish(chosen, fitters, models, params.polish_points)
    t = lap("pose", t)
    used: set[int] = set().union(*(g for g, _ in chosen.values())) if chosen else set()
    poses = {i: EstimatedPose(Pose.from_matrix(f.T), f.score, models[i].type, f.fitness, f.coverage, f.rmse)
             for i, (g, f) in chosen.items() if i not in ambiguous and i in wanted}
    unknown_clusters = tuple(pc for c, pc in enumerate(clusters) if c not in used)
    obstacles = _obstacles(clusters, unknown_clusters, chosen, models, plane, params)
    t = lap("obstacles", t)
    timings["total"] = t - t0

    missing = [i for i in wanted if i not in poses and i not in ambiguous]
    amb = [i for i in wanted if i in ambiguous]
    if amb:
        status, msg = S.AMBIGUOUS, f"look-alike clusters for {amb}: identity cannot be decided"
    elif missing:
        status, msg = S.OBJECT_MISSING, f"not found in view: {missing}"
    else:
        status, msg = S.OK, f"{len(poses)} object(s), {len(unknown_clusters)} unknown cluster(s)"
    return PerceptionResult(status, msg, poses, obstacles, tuple(clusters), unknown_clusters, plane, timings)

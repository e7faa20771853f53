"""Model-based 6D pose of one segmented cluster: hypotheses, refinement, scoring (FoundationPose-style).

FoundationPose (the paper's estimator) needs network weights and a GPU; this module keeps its
structure with classical parts:
  1. hypotheses - objects rest upright on the table, so a sweep of yaws about the table normal
     (one symmetry period only) placed at the cluster covers every distinct pose, and a cluster
     that reaches the table takes its height from contact; optionally FPFH + RANSAC global
     registration adds free 6-DOF hypotheses;
  2. refinement - a batched coarse ICP of all yaws through the model's nearest-point grid, then
     symmetric trimmed ICP (cluster -> model and visible model -> cluster) in 4 DOF for the best
     few; open3d point-to-plane ICP for 6-DOF hypotheses;
  3. scoring - fitness (cluster points explained by the model) x coverage (model points the
     camera should see, per visibility.py, that have data near them), plus inlier RMSE;
  4. selection - the best score; symmetric yaws are never compared since only one period is swept.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree

from .cloud import to_o3d
from .models import ObjectModel, nearest_grid
from .visibility import OcclusionMap, visible_mask

_UP = np.array([0.0, 0.0, 1.0])
_HALF_TURNS = [np.diag(d) for d in ([1.0, 1, 1, 1], [1.0, -1, -1, 1], [-1.0, 1, -1, 1], [-1.0, -1, 1, 1])]


@dataclass(frozen=True)
class PoseParams:
    """Knobs of hypothesis generation, refinement and scoring (metres, radians)."""

    yaw_steps: int = 24              # hypotheses over a full turn; divided by the symmetry order
    coarse_iterations: int = 6
    fine_iterations: int = 12
    keep: int = 2                    # hypotheses refined after the coarse round
    rank: int = 6                    # coarse survivors (by fitness) ranked by the full score
    coarse_points: int = 100         # cluster / model subsample sizes per ICP round
    fine_points: int = 250
    score_points: int = 400          # cluster / visible-model samples behind a final score
    refine_ratio: float = 0.8        # refine runners-up only if their coarse score is this close
    min_coarse_score: float = 0.1    # below this after the coarse round the model is not refined
    max_correspondence: float = 0.02  # first ICP round's gate, annealed down to 2 * inlier_distance
    inlier_distance: float = 0.004   # scoring gate (about 3 sigma of depth noise + sampling)
    upright: bool = True             # yaw-sweep hypotheses for objects resting on the table
    global_registration: bool = False  # add FPFH + RANSAC 6-DOF hypotheses
    rest_on_table: bool = True       # clusters that reach the table rest on it (height from contact)
    rest_contact: float = 0.015      # "reaches the table": lowest points within this height
    fpfh_voxel: float = 0.005
    large_radius: float = 0.14       # models with a wider footprint radius get shifted centre hypotheses
    large_shift: float = 0.06        # +- this far in x and y (a grid max_correspondence apart)
    prune_after: int = 2             # coarse rounds on every hypothesis before only the best prune_keep go on
    prune_keep: int = 96             # (a large model: 49 centres x 24 yaws = 1176, most of a Coffee Prep frame)


@dataclass(frozen=True)
class Fit:
    """One refined hypothesis: model->world transform and its scores."""

    T: np.ndarray
    fitness: float    # fraction of cluster points within inlier_distance of the model surface
    coverage: float   # fraction of camera-facing model points within inlier_distance of the cluster
    rmse: float       # RMS distance of the inlier cluster points

    @property
    def score(self) -> float:
        return self.fitness * self.coverage


def _rot_to(n: np.ndarray) -> np.ndarray:
    """Smallest rotation taking +z to unit vector n (the table tilt)."""
    v = np.cross(_UP, n)
    s, c = np.linalg.norm(v), float(_UP @ n)
    if s < 1e-9:
        return np.eye(3)
    k = v / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * K + (1 - c) * K @ K


def _rz(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@lru_cache(maxsize=256)
def _model_subsample(model: ObjectModel, k: int) -> np.ndarray:
    """A fixed, evenly spread subset of the model's points (indices) for the model -> cluster term."""
    return np.arange(len(model.points)) if len(model.points) <= k else np.linspace(
        0, len(model.points) - 1, k).astype(int)


def _subsample(n: int, k: int, rng: np.random.Generator) -> np.ndarray:
    return np.arange(n) if n <= k else rng.choice(n, k, replace=False)


class ClusterFitter:
    """Fits models to one cluster; the cluster's KD-tree is built once and shared by all models."""

    def __init__(self, points: np.ndarray, up: np.ndarray, params: PoseParams,
                 camera: np.ndarray | None = None, seed: int = 0, table_offset: float | None = None,
                 occlusion: OcclusionMap | None = None):
        """table_offset: d of the table plane n.x + d = 0 (n = up). When given and the cluster
        reaches down to the table, the object is taken to rest on it: its height is fixed by
        contact instead of being fitted, which removes the depth-noise bias thin-walled or
        flat objects otherwise show in z."""
        self.q = np.asarray(points, float)
        self.tree = cKDTree(self.q)
        self.up = np.asarray(up, float) / np.linalg.norm(up)
        self.R_up = _rot_to(self.up)
        self.table_z: float | None = None
        if table_offset is not None and params.rest_on_table:
            h = self.q @ self.up + table_offset
            if np.percentile(h, 1) < params.rest_contact:
                self.table_z = -float(table_offset)
        self.p = params
        self.camera = None if camera is None else np.asarray(camera, float)
        self.occlusion = occlusion
        self.rng = np.random.default_rng(seed)

    # ------------------------------------------------------------------ hypotheses
    def upright_hypotheses(self, model: ObjectModel) -> tuple[np.ndarray, np.ndarray]:
        """Yaws over one symmetry period, each placed at the cluster (top surfaces aligned), as rotations
        (H, 3, 3) and translations (H, 3) in the table frame. A large object (footprint radius over
        large_radius: Coffee's 30 cm machine) seen from one side is a cluster whose centre lies up to ~5 cm
        nearer the camera than the object's, beyond the coarse ICP's reach (max_correspondence): its
        hypotheses also take centres on a grid within +-large_shift."""
        qu = self.q @ self.R_up  # cluster in the upright (table) frame
        c_xy = 0.5 * (qu[:, :2].min(axis=0) + qu[:, :2].max(axis=0))
        order = model.symmetry.order
        k = 1 if order == 0 else max(int(np.ceil(self.p.yaw_steps / order)), 1)
        period = 2 * np.pi if order == 0 else model.symmetry.yaw_period
        m_c = 0.5 * (model.lo + model.hi)
        shifts = np.zeros((1, 2))
        if model.xy_radius > self.p.large_radius:  # a grid of centres, max_correspondence apart
            g = np.arange(-self.p.large_shift, self.p.large_shift + 1e-9, self.p.max_correspondence)
            shifts = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
        Rk = np.stack([_rz(yaw) for yaw in np.arange(k) * period / k])                   # (k, 3, 3)
        R = np.repeat(Rk, len(shifts), axis=0)                                              # yaw-major
        t = np.empty((len(R), 3))
        centres = np.repeat(c_xy - (Rk @ m_c)[:, :2], len(shifts), axis=0)
        t[:, :2] = centres + np.tile(shifts, (k, 1))
        t[:, 2] = qu[:, 2].max() - model.hi[2] if self.table_z is None else self.table_z - model.lo[2]
        return R, t

    def global_hypotheses(self, model: ObjectModel, n: int = 2) -> list[np.ndarray]:
        """FPFH + RANSAC registrations of the model onto the cluster (6 DOF, any orientation)."""
        v = self.p.fpfh_voxel
        src, src_f = _fpfh_model(model, v)
        tgt = to_o3d(self.q).voxel_down_sample(v)
        if len(tgt.points) < 10:
            return []
        tgt.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2.5 * v, max_nn=30))
        tgt_f = o3d.pipelines.registration.compute_fpfh_feature(
            tgt, o3d.geometry.KDTreeSearchParamHybrid(radius=5 * v, max_nn=100))
        reg = o3d.pipelines.registration
        out = []
        for i in range(n):
            o3d.utility.random.seed(int(self.rng.integers(1 << 31)))
            with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
                res = reg.registration_ransac_based_on_feature_matching(
                    src, tgt, src_f, tgt_f, True, 1.5 * v, reg.TransformationEstimationPointToPoint(False), 3,
                    [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9),
                     reg.CorrespondenceCheckerBasedOnDistance(1.5 * v)],
                    reg.RANSACConvergenceCriteria(20000, 0.999))
            T = np.asarray(res.transformation).copy()
            # Partial views of flat parts often register upside down: try the half turns too.
            out += [T @ F for F in _HALF_TURNS]
        return out

    def _to_world(self, R: np.ndarray, t: np.ndarray) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = self.R_up @ R
        T[:3, 3] = self.R_up @ t
        return T

    # ------------------------------------------------------------------ refinement
    def coarse_upright(self, model: ObjectModel, R: np.ndarray,
                       t: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
        """A few cluster -> model ICP rounds for all yaw hypotheses (table-frame R (H, 3, 3), t (H, 3),
        upright_hypotheses) at once (one grid query per round); the survivors' world poses and fitness."""
        p = self.p
        lock_yaw = model.symmetry.order == 0
        qu = self.q[_subsample(len(self.q), p.coarse_points, self.rng)] @ self.R_up      # (n, 3)
        H, n = len(R), len(qu)
        grid = nearest_grid(model)
        gates = np.geomspace(p.max_correspondence, 2 * p.inlier_distance, max(p.coarse_iterations, 1))
        for it, gate in enumerate(gates):
            local = (qu[None] - t[:, None]) @ R                  # model frame
            d, j = grid.query(local.reshape(-1, 3), gate)
            w = np.isfinite(d).reshape(H, n).astype(float)
            if it == p.prune_after and H > p.prune_keep:  # a large model's shifted centres: keep the leaders
                top = np.argsort(-w.mean(axis=1), kind="stable")[: p.prune_keep]
                R, t, w, j, H = R[top], t[top], w[top], j.reshape(-1, n)[top].reshape(-1), len(top)
            P = model.points[np.minimum(j, len(model.points) - 1)].reshape(H, n, 3)
            z = t[:, 2].copy()
            R, t = _fit_yaw_translation_batch(P, qu, w, R if lock_yaw else None, R, t)
            if self.table_z is not None:
                t[:, 2] = z
        local = (qu[None] - t[:, None]) @ R
        d, _ = grid.query(local.reshape(-1, 3), p.inlier_distance)
        fitness = np.isfinite(d).reshape(H, n).mean(axis=1)
        return [self._to_world(R[h], t[h]) for h in range(H)], fitness

    def refine_upright(self, model: ObjectModel, T: np.ndarray, iterations: int, n_points: int) -> np.ndarray:
        """Symmetric trimmed point-to-point ICP over yaw + translation in the table frame."""
        lock_yaw = model.symmetry.order == 0
        qi = self.q[_subsample(len(self.q), n_points, self.rng)]
        qu_all = qi @ self.R_up
        msub = _model_subsample(model, n_points)
        grid = nearest_grid(model)
        Ru = self.R_up.T @ T[:3, :3]
        tu = self.R_up.T @ T[:3, 3]
        gates = np.geomspace(4 * self.p.inlier_distance, 2 * self.p.inlier_distance, max(iterations, 1))
        for it, gate in enumerate(gates):
            Tw = self._to_world(Ru, tu)
            if it % 4 == 0:  # visibility changes slowly with the pose
                vis = visible_mask(model, Tw, self.camera)
                mi = model.points[msub[vis[msub]]]
            d1, j1 = grid.query((qu_all - tu) @ Ru, gate)                               # cluster -> model
            k1 = np.isfinite(d1)
            d2, j2 = self.tree.query(mi @ Tw[:3, :3].T + Tw[:3, 3], distance_upper_bound=gate)  # model -> cluster
            k2 = np.isfinite(d2)
            P = np.concatenate([model.points[j1[k1]], mi[k2]])          # model frame
            Q = np.concatenate([qu_all[k1], self.q[j2[k2]] @ self.R_up])  # table frame
            if len(P) < 6:
                break
            Ru_new, tu_new = _fit_yaw_translation(P, Q, Ru if lock_yaw else None)
            if self.table_z is not None:
                tu_new[2] = tu[2]
            done = np.linalg.norm(tu_new - tu) < 1e-4 and abs(Ru_new[0, 1] - Ru[0, 1]) < 1e-3  # 0.1 mm, 0.06 deg
            Ru, tu = Ru_new, tu_new
            if done:
                break
        return self._to_world(Ru, tu)

    def refine_6dof(self, model: ObjectModel, T: np.ndarray, iterations: int) -> np.ndarray:
        """open3d point-to-plane ICP, cluster -> model surface, with an annealed gate."""
        reg = o3d.pipelines.registration
        src = to_o3d(self.q[_subsample(len(self.q), self.p.fine_points, self.rng)])
        tgt = _model_cloud(model)
        Tinv = np.linalg.inv(T)
        for gate in (self.p.max_correspondence, 4 * self.p.inlier_distance, 2 * self.p.inlier_distance):
            Tinv = reg.registration_icp(src, tgt, gate, Tinv, reg.TransformationEstimationPointToPlane(),
                                        reg.ICPConvergenceCriteria(max_iteration=max(iterations // 3, 1))
                                        ).transformation
        return np.linalg.inv(np.asarray(Tinv))

    # ------------------------------------------------------------------ scoring
    def score(self, model: ObjectModel, T: np.ndarray, n_points: int, exact: bool = False,
              sample: np.ndarray | None = None) -> Fit:
        """Fitness, coverage and RMSE of pose T from (at most) n_points cluster points and as many
        visible model points. exact: KD-tree distances to the model's dense surface (final scores)
        instead of the lookup grid (ranking); the grid's distances are exact to the point it finds,
        which may not be the nearest one near sharp features. sample: the cluster points' indices,
        shared by the hypotheses being compared, with evenly spread model points: their scores then
        differ by the poses only, not by two random draws (a drawer's handle, the one feature that
        tells it from its half-turn, is a few percent of its points: about one draw's noise)."""
        tau = self.p.inlier_distance
        q = self.q[_subsample(len(self.q), n_points, self.rng) if sample is None else sample]
        local = (q - T[:3, 3]) @ T[:3, :3]
        d = (model.surface_tree.query(local, distance_upper_bound=tau)[0] if exact
             else nearest_grid(model).query(local, tau)[0])
        inl = np.isfinite(d)
        mv = model.points[visible_mask(model, T, self.camera)]
        if len(mv) > n_points:
            mv = mv[_subsample(len(mv), n_points, self.rng) if sample is None
                    else np.linspace(0, len(mv) - 1, n_points).astype(int)]
        mw = mv @ T[:3, :3].T + T[:3, 3]
        if self.occlusion is not None:   # hidden behind something the camera saw: not a miss
            mw = mw[~self.occlusion.occluded(mw, max(4 * tau, 0.01))]
        coverage = 0.0
        if len(mw):
            d2, _ = self.tree.query(mw, distance_upper_bound=tau)
            coverage = float(np.isfinite(d2).mean())
        rmse = float(np.sqrt(np.mean(d[inl] ** 2))) if inl.any() else float("inf")
        return Fit(T, float(inl.mean()) if len(q) else 0.0, coverage, rmse)

    # ------------------------------------------------------------------ all together
    def fit(self, model: ObjectModel) -> Fit:
        """Best refined hypothesis of `model` on this cluster (coarse round, then the top few refined)."""
        p = self.p
        coarse: list[tuple[np.ndarray, bool]] = []
        if p.upright:
            Ts, fitness = self.coarse_upright(model, *self.upright_hypotheses(model))
            # cheap cluster->model fitness preselects; the full score (with coverage) ranks the rest
            coarse += [(Ts[i], True) for i in np.argsort(-fitness)[: p.rank]]
        if p.global_registration or not p.upright:
            coarse += [(self.refine_6dof(model, T, p.coarse_iterations), False)
                       for T in self.global_hypotheses(model)]
        ranked = sorted(((self.score(model, T, p.coarse_points).score, i) for i, (T, _) in enumerate(coarse)),
                        reverse=True)
        best: Fit | None = None
        final = _subsample(len(self.q), p.score_points, self.rng)   # one draw scores every refined pose
        for sc, i in ranked[: p.keep]:
            if sc < p.refine_ratio * ranked[0][0] or sc < p.min_coarse_score:
                break  # clearly worse than the leader, or no match at all: not worth refining
            T, upright = coarse[i]
            T2 = (self.refine_upright(model, T, p.fine_iterations, p.fine_points) if upright
                  else self.refine_6dof(model, T, p.fine_iterations))
            f = self.score(model, T2, p.score_points, exact=True, sample=final)
            if best is None or f.score > best.score or (f.score == best.score and f.rmse < best.rmse):
                best = f
        if best is None:  # nothing refined: report the coarse leader as it is
            T, _ = coarse[ranked[0][1]]
            best = self.score(model, T, p.score_points, exact=True)
        return best


def _fit_yaw_translation(P: np.ndarray, Q: np.ndarray, R_fixed: np.ndarray | None):
    """Least-squares Rz(yaw), t with Rz P + t ~= Q (2D Procrustes in xy, mean offset in z)."""
    pc, qc = P.mean(axis=0), Q.mean(axis=0)
    if R_fixed is None:
        a, b = P[:, :2] - pc[:2], Q[:, :2] - qc[:2]
        yaw = np.arctan2(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]), np.sum(a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]))
        R = _rz(yaw)
    else:
        R = R_fixed
    return R, qc - R @ pc


def _fit_yaw_translation_batch(P: np.ndarray, Q: np.ndarray, w: np.ndarray, R_fixed, R_prev, t_prev):
    """_fit_yaw_translation for H hypotheses at once: P (H, n, 3) model, Q (n, 3) table, w (H, n)."""
    cnt = w.sum(axis=1)
    ok = cnt >= 6
    ws = w / np.maximum(cnt, 1)[:, None]
    pc = np.einsum("hn,hni->hi", ws, P)
    qc = ws @ Q
    if R_fixed is None:
        a = P[..., :2] - pc[:, None, :2]
        b = Q[None, :, :2] - qc[:, None, :2]
        s = np.einsum("hn,hn->h", w, a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])
        c = np.einsum("hn,hn->h", w, a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1])
        yaw = np.arctan2(s, c)
        R = np.zeros((len(P), 3, 3))
        R[:, 0, 0] = R[:, 1, 1] = np.cos(yaw)
        R[:, 1, 0] = np.sin(yaw)
        R[:, 0, 1] = -np.sin(yaw)
        R[:, 2, 2] = 1.0
    else:
        R = R_fixed
    t = qc - np.einsum("hij,hj->hi", R, pc)
    R = np.where(ok[:, None, None], R, R_prev)
    t = np.where(ok[:, None], t, t_prev)
    return R, t


@lru_cache(maxsize=64)
def _model_cloud(model: ObjectModel) -> o3d.geometry.PointCloud:
    pc = to_o3d(model.points)
    pc.normals = o3d.utility.Vector3dVector(model.normals)
    return pc


@lru_cache(maxsize=64)
def _fpfh_model(model: ObjectModel, voxel: float):
    pc = _model_cloud(model).voxel_down_sample(voxel)
    pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2.5 * voxel, max_nn=30))
    f = o3d.pipelines.registration.compute_fpfh_feature(
        pc, o3d.geometry.KDTreeSearchParamHybrid(radius=5 * voxel, max_nn=100))
    return pc, f

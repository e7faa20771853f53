"""Why a point-cloud goal is refused: replay chosen problems of bench/planning/run.py and name the
cloud cells that block collision-free (ground-truth) goal configurations.

For each problem: the goal's IK solutions (no collision filter), each checked against the ground
truth (pybullet meshes), the cloud without the hidden space, and the hidden cells. For each hidden
cell that blocks a configuration the ground truth allows: is it seen by some camera (a ray from the
camera to the cell's centre reaches it: the certification missed it), or truly hidden, and then how
far behind the occluder's surface along that ray (depth) and how far from the nearest box.

    python bench/planning/diagnose.py --problems 1:10,1:48 [--shadow-px 4]
"""
from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from collections import Counter  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.planning.run import GroundTruth, make_problem  # noqa: E402
from skillgen_ros.core.planning.collision import CollisionModel, heightmap_fill  # noqa: E402
from skillgen_ros.core.planning.ik import IKSolver  # noqa: E402
from skillgen_ros.core.planning.kinematics import PandaKinematics  # noqa: E402
from skillgen_ros.core.planning.occlusion import hidden_space  # noqa: E402
from skillgen_ros.core.sim import camera as cam  # noqa: E402


def gt_clearance(gt, q):
    """Smallest distance (m) robot - boxes/table (negative = penetration), up to 5 cm."""
    gt.set_q(q)
    best = 0.05
    for body in gt.boxes + [gt.table]:
        for c in gt.p.getClosestPoints(gt.robot, body, 0.05):
            if body == gt.table and c[3] in (-1, 0):
                continue
            best = min(best, c[8])
    return best


def cell_report(gt, views, names, cell, boxes):
    """(visible_from, occluders, depth behind the occluder, distance to the nearest box)."""
    seen, occ, depth = [], [], []
    for v, name in zip(views, names):
        u, vv, z = v.project(cell[None])
        h, w = v.depth.shape
        if not (z[0] > 0 and 0 <= u[0] < w and 0 <= vv[0] < h):
            continue
        o = v.T_world_camera[:3, 3]
        hit = gt.p.rayTest(o.tolist(), cell.tolist())[0]
        if hit[0] < 0 or hit[2] > 0.999:
            seen.append(name)
        else:
            body = hit[0]
            who = "table" if body == gt.table else "robot" if body == gt.robot else f"box{gt.boxes.index(body)}"
            occ.append(f"{name}:{who}")
            depth.append(np.linalg.norm(cell - np.asarray(hit[3])))
    d_box = min(signed_box_distance(b, cell) for b in boxes)
    return seen, occ, depth, d_box


def signed_box_distance(b, x):
    local = np.abs((x - b.pose[:3, 3]) @ b.pose[:3, :3]) - b.half_extents
    return float(np.linalg.norm(np.maximum(local, 0)) + min(local.max(), 0))


def certify_detail(v, c, voxel=0.01, slope_px=2.0):
    """Why a view does (not) certify cell c: the window of occlusion._certified_free and the
    enclosing pixel block of the cell's projected corners."""
    u, vv, z = v.project(c[None])
    h, w = v.depth.shape
    f = float(max(v.K[0, 0], v.K[1, 1]))
    half = 0.5 * np.sqrt(3.0) * voxel
    if not (z[0] > half and 0 <= u[0] < w and 0 <= vv[0] < h):
        return "out of view"
    z = z[0]
    foot = int(np.ceil(half * f / (z - half))) + 1
    need = z + half + slope_px * z / f
    seen = np.nan_to_num(v.depth, nan=0.0)
    ui, vi = int(u[0]), int(vv[0])
    win = seen[max(0, vi - foot):vi + foot + 1, max(0, ui - foot):ui + foot + 1]
    corners = c + 0.5 * voxel * np.array([[a, b, d] for a in (-1, 1) for b in (-1, 1) for d in (-1, 1)])
    pc = (corners - v.T_world_camera[:3, 3]) @ v.T_world_camera[:3, :3]
    uc = v.K[0, 0] * pc[:, 0] / pc[:, 2] + v.K[0, 2]
    vc = v.K[1, 1] * pc[:, 1] / pc[:, 2] + v.K[1, 2]
    u0, u1 = int(np.floor(uc.min())), int(np.ceil(uc.max()))
    v0, v1 = int(np.floor(vc.min())), int(np.ceil(vc.max()))
    enc = seen[max(0, v0):v1 + 1, max(0, u0):u1 + 1]
    need_half = pc[:, 2].max() + slope_px * z / f
    return (f"z={z:.3f} foot={foot} win_min={win.min():.3f} need={need:.3f} "
            f"| enclosing {u1 - u0 + 1}x{v1 - v0 + 1} min={enc.min():.3f} need(corners)={need_half:.3f} "
            f"need0={pc[:, 2].max():.3f}")


def diagnose(seed, i, problem, kin, gt, cfgs, shadow_px):
    boxes, start, goal = problem
    gt.set_boxes(boxes)
    cm = CollisionModel(kin, table_z=GroundTruth.TABLE_TOP_Z)
    cm.set_boxes([], as_obstacles=False)
    pts, views = gt.cloud(start, cfgs)
    names = [c.name for c in cfgs]
    cm.set_point_cloud(pts, self_filter_q=start, fill_below=True)
    no_hidden = cm.cloud.copy()
    cm.set_point_cloud(pts, self_filter_q=start, fill_below=True, views=views, shadow_px=shadow_px)
    full = cm.cloud.copy()
    # the hidden cells alone (as set_point_cloud computes them)
    C, R = cm._spheres_world(np.asarray(start, float).reshape(1, 7))[:2]
    from scipy.spatial import cKDTree

    def on_robot(X):
        hit = np.zeros(len(X), bool)
        for k in cKDTree(X).query_ball_point(C[0], R + 0.02):
            hit[k] = True
        return hit
    H = hidden_space(views, cm.table_z, on_robot, 0.01, shadow_px=shadow_px)
    H = H[~on_robot(H)] if len(H) else H
    ik = IKSolver(kin, rng=0)
    sols = ik.solve(goal, seed_q=start, timeout=5.0, max_solutions=40, max_iterations=8000).solutions
    out = Counter()
    blockers = {}
    for q in sols:
        clear = gt_clearance(gt, q)
        cm.cloud = no_hidden
        cm._trees = {}
        free_nh = not cm.in_collision(q[None])[0]
        cm.cloud = full
        cm._trees = {}
        free_full = not cm.in_collision(q[None])[0]
        tag = ("gt_hit" if clear <= 0 else "gt_free") + ("/nohidden_free" if free_nh else "/nohidden_hit") \
            + ("/full_free" if free_full else "/full_hit")
        out[tag] += 1
        if clear > 0 and free_nh and not free_full:
            Cq, Rq, _ = cm._spheres_world(q[None])
            tree = cKDTree(Cq[0])
            for k, c in enumerate(H):
                dd, j = tree.query(c)
                if np.any(np.linalg.norm(Cq[0] - c, axis=1) < Rq + cm.cloud_margin):
                    blockers[tuple(np.round(c, 3))] = c
        elif clear > 0 and not free_nh:
            # which observed/fill points block it: near which box, how far out
            Cq, Rq, _ = cm._spheres_world(q[None])
            P = no_hidden
            d = np.linalg.norm(P[:, None, :] - Cq[0][None], axis=2) - Rq[None]
            hit = np.any(d < cm.cloud_margin, axis=1)
            db = [min(signed_box_distance(b, p) for b in boxes) for p in P[hit]]
            out[f"nohidden_blocker_box_dist_max={max(db):.3f}" if db else "self/table (no cloud point)"] += 1
    print(f"seed {seed} problem {i}: {len(sols)} IK solutions, hidden cells {len(H)}; {dict(out)}")
    causes = Counter()
    for c in blockers.values():
        seen, occ, depth, d_box = cell_report(gt, views, names, c, boxes)
        key = ("seen by " + "+".join(seen)) if seen else "hidden"
        causes[key] += 1
        print(f"   cell {np.round(c, 3)} seen={seen} occluded={occ} depth={np.round(depth, 3)} "
              f"box_dist={d_box:.3f}")
        for v, name in zip(views, names):
            print("      ", name, certify_detail(v, c))
    print(f"   blockers: {dict(causes)}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", required=True, help="seed:index,... e.g. 1:10,3:44")
    ap.add_argument("--n", type=int, default=100, help="problems per seed in the bench run")
    ap.add_argument("--shadow-px", type=float, default=4.0)
    args = ap.parse_args()
    want = {}
    for part in args.problems.split(","):
        s, k = part.split(":")
        want.setdefault(int(s), []).append(int(k))
    kin = PandaKinematics()
    cm = CollisionModel(kin, table_z=GroundTruth.TABLE_TOP_Z)
    gt = GroundTruth()
    cfgs = (cam.CameraConfig("front"), cam.CameraConfig("wrist"))
    for seed, idx in want.items():
        ik = IKSolver(kin, rng=seed)
        rng = np.random.default_rng(seed)
        problems = [make_problem(rng, kin, ik, cm) for _ in range(max(idx) + 1)]
        for k in idx:
            diagnose(seed, k, problems[k], kin, gt, cfgs, args.shadow_px)


if __name__ == "__main__":
    main()

"""Why a point-cloud goal is refused: replay chosen problems of bench/planning/run.py and name what
blocks goal configurations the ground truth allows.

For each problem: 40 IK solutions of the goal (no collision filter), each checked against the
ground truth (pybullet meshes), the cloud without the hidden space, and with it. A configuration
that is truly free but blocked by the cloud alone is a tight goal (the 1 cm margin, the spheres'
overshoot); one blocked only with the hidden space names the hidden cells in its way: for each,
which camera sees its centre (a ray from the camera reaches it, the robot at the start), which
occludes it (and by what), whether the camera's certification window holds a nearer surface (the
cell is within a pixel or two of a silhouette: the uncertain band), and its distance to the
nearest true box.

    python bench/planning/diagnose.py --problems 1:10,3:44 [--hidden-refine 2]

Problems are rebuilt from the seed as run.py builds them; the goal IK differs from the bench's
(its own rng), so this explains refusals, it does not replay the bench's exact plan.
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
from scipy.spatial import cKDTree  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.planning.run import GroundTruth, make_problem  # noqa: E402
from skillgen_ros.core.planning.collision import HIDDEN_REFINE, CollisionModel  # noqa: E402
from skillgen_ros.core.planning.ik import IKSolver  # noqa: E402
from skillgen_ros.core.planning.kinematics import PandaKinematics  # noqa: E402
from skillgen_ros.core.planning.occlusion import hidden_space  # noqa: E402
from skillgen_ros.core.sim import camera as cam  # noqa: E402


def gt_clearance(gt, q) -> float:
    """Smallest distance (m) robot - boxes/table (negative = penetration), up to 5 cm."""
    gt.set_q(q)
    best = 0.05
    for body in gt.boxes + [gt.table]:
        for c in gt.p.getClosestPoints(gt.robot, body, 0.05):
            if body == gt.table and c[3] in (-1, 0):
                continue
            best = min(best, c[8])
    return best


def signed_box_distance(b, x) -> float:
    local = np.abs((x - b.pose[:3, 3]) @ b.pose[:3, :3]) - b.half_extents
    return float(np.linalg.norm(np.maximum(local, 0)) + min(local.max(), 0))


def view_of_cell(gt, v, cell, width, edge_px=1):
    """'out', or (seen centre: bool, occluder name or None, nearer surface in the window: bool)."""
    u, vv, z = v.project(cell[None])
    h, w = v.depth.shape
    if not (z[0] > 0 and 0 <= u[0] < w and 0 <= vv[0] < h):
        return "out"
    hit = gt.p.rayTest(v.T_world_camera[:3, 3].tolist(), cell.tolist())[0]
    occ = None
    if hit[0] >= 0 and hit[2] < 0.999:
        occ = "table" if hit[0] == gt.table else "robot" if hit[0] == gt.robot else f"box{gt.boxes.index(hit[0])}"
    f = float(max(v.K[0, 0], v.K[1, 1]))
    half = 0.5 * np.sqrt(3.0) * width
    r = int(np.ceil(half * f / (z[0] - half))) + edge_px
    ui, vi = int(u[0]), int(vv[0])
    win = np.nan_to_num(v.depth, nan=0.0)[max(0, vi - r):vi + r + 1, max(0, ui - r):ui + r + 1]
    return occ is None, occ, bool(win.min() < z[0] + half)


def diagnose(seed, i, problem, kin, gt, cfgs, refine):
    boxes, start, goal = problem
    gt.set_boxes(boxes)
    cm = CollisionModel(kin, table_z=GroundTruth.TABLE_TOP_Z)
    cm.set_boxes([], as_obstacles=False)
    pts, views = gt.cloud(start, cfgs)
    names = [c.name for c in cfgs]
    cm.set_point_cloud(pts, self_filter_q=start, fill_below=True)
    surfaces = cm.cloud.copy()
    cm.set_point_cloud(pts, self_filter_q=start, fill_below=True, views=views, hidden_refine=refine)
    full = cm.cloud.copy()
    C, R = cm._spheres_world(np.asarray(start, float).reshape(1, 7))[:2]

    def on_robot(X):
        hit = np.zeros(len(X), bool)
        for k in cKDTree(X).query_ball_point(C[0], R + 0.02):
            hit[k] = True
        return hit
    H = hidden_space(views, cm.table_z, on_robot, 0.01, shadow_px=4.0, refine=refine)
    H = H[~on_robot(H)] if len(H) else H
    width = 0.01 / 2 ** refine
    sols = IKSolver(kin, rng=0).solve(goal, seed_q=start, timeout=5.0, max_solutions=40,
                                      max_iterations=8000).solutions
    tally, blockers = Counter(), {}
    for q in sols:
        clear = gt_clearance(gt, q)
        free = []
        for cloud in (surfaces, full):
            cm.cloud, cm._trees = cloud, {}
            free.append(not cm.in_collision(q[None])[0])
        tally[("truly free" if clear > 0 else "truly hit") + (", surfaces free" if free[0] else ", surfaces hit")
              + (", hidden free" if free[1] else ", hidden hit")] += 1
        if clear > 0 and free[0] and not free[1]:
            Cq, Rq, _ = cm._spheres_world(q[None])
            d = np.linalg.norm(full[:, None, :] - Cq[0][None], axis=2) - Rq[None] - cm.cloud_margin
            for p in full[np.any(d < 0, axis=1)]:
                # the hidden cell that put this point there: itself, or the one its column fills down from
                col = np.all(np.abs(H[:, :2] - p[:2]) <= 0.5 * width + 0.0026, axis=1) & (H[:, 2] >= p[2] - 1e-9)
                for c in H[col][:1] if col.any() else ():
                    blockers[tuple(np.round(c, 4))] = c
    print(f"seed {seed} problem {i}: {len(sols)} goal IK solutions: {dict(tally)}")
    gt.set_q(start)  # the cameras saw the scene with the robot at the start
    causes = Counter()
    for c in blockers.values():
        per = {n: view_of_cell(gt, v, c, width) for v, n in zip(views, names)}
        d_box = min(signed_box_distance(b, c) for b in boxes)
        seen = [n for n, r in per.items() if r != "out" and r[0]]
        band = [n for n, r in per.items() if r != "out" and r[0] and r[2]]
        occl = [f"{n}:{r[1]}" for n, r in per.items() if r != "out" and not r[0]]
        cause = (f"seen by {'+'.join(seen)}, in the silhouette band of {'+'.join(band)}" if seen and band
                 else f"seen by {'+'.join(seen)}" if seen else f"hidden ({', '.join(occl) or 'out of view'})")
        causes[cause] += 1
        print(f"   cell {np.round(c, 4)} box {d_box * 1e3:5.1f} mm  {per}")
    print(f"   blocking hidden cells: {dict(causes)}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", required=True, help="seed:index,... e.g. 1:10,3:44")
    ap.add_argument("--hidden-refine", type=int, default=HIDDEN_REFINE)
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
            diagnose(seed, k, problems[k], kin, gt, cfgs, args.hidden_refine)


if __name__ == "__main__":
    main()

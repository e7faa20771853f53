"""Planning benchmark: a seeded suite of tabletop problems among clutter boxes.

Each problem (random boxes, a random collision-free start, a random reachable collision-free goal
pose over the table) is planned twice: with the scene boxes, and with the point cloud that the
sim's front and wrist cameras (skillgen_ros.core.sim.camera, pybullet TinyRenderer) see of the
same scene, self-filtered, with the space hidden behind what the cameras saw (their depth views;
core/planning/occlusion.py) and heightmap-filled (CollisionModel.set_point_cloud(fill_below=True,
views=...); its cost is reported separately as cloud_prep; planning time is planner.plan). Every
returned trajectory is checked densely (every 5 mm of robot motion) against the ground-truth boxes
and the table with pybullet's mesh distance queries -- independent of the sphere model. The
planner's table is the bench's own (top at z = 0). Each seed's colliding plans and deepest
penetration are recorded (results.<mode>.per_seed).

    python bench/planning/run.py [--quick] [--problems N] [--seeds 0-4 | --seed S] [--no-occlusion]
"""
from __future__ import annotations

import os

# Small matrices only: BLAS threads would just contend with each other (and other processes).
for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pybullet as pb  # noqa: E402
from pybullet_utils.bullet_client import BulletClient  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.machine import machine_info  # noqa: E402

from skillgen_ros.core.geometry import Pose  # noqa: E402
from skillgen_ros.core.planning.collision import Box, CollisionModel  # noqa: E402
from skillgen_ros.core.planning.ik import IKSolver  # noqa: E402
from skillgen_ros.core.planning.kinematics import PandaKinematics  # noqa: E402
from skillgen_ros.core.planning.occlusion import DepthView  # noqa: E402
from skillgen_ros.core.planning.planner import Mode, MotionPlanner  # noqa: E402
from skillgen_ros.core.robot import ARM_JOINTS, FINGER_JOINTS, HAND_LINK, Q_HOME, panda_urdf_path  # noqa: E402
from skillgen_ros.core.sim import camera as cam  # noqa: E402


def random_boxes(rng, n):
    boxes = []
    while len(boxes) < n:
        h = np.array([*rng.uniform(0.02, 0.06, 2), rng.uniform(0.03, 0.12)])
        xy = rng.uniform([0.3, -0.45], [0.75, 0.45])
        if np.linalg.norm(xy) < 0.3:
            continue
        T = np.eye(4)
        T[:3, :3] = Rotation.from_euler("z", rng.uniform(-np.pi, np.pi)).as_matrix()
        T[:3, 3] = (*xy, h[2])
        boxes.append(Box(f"box{len(boxes)}", T, h))
    return boxes


def random_pose(rng) -> Pose:
    p = rng.uniform([0.3, -0.4, 0.12], [0.7, 0.4, 0.45])
    R = (Rotation.from_euler("z", rng.uniform(-np.pi, np.pi)) * Rotation.from_euler("x", np.pi)
         * Rotation.from_rotvec(rng.normal(0, 0.2, 3)))
    return Pose(p, R.as_quat())


def make_problem(rng, kin, ik, cm, n_boxes=(4, 8)):
    """Boxes, a start configuration and a goal pose, all collision-free for the scene model."""
    while True:
        boxes = random_boxes(rng, int(rng.integers(n_boxes[0], n_boxes[1] + 1)))
        cm.set_boxes(boxes)
        cm.set_point_cloud(np.empty((0, 3)))
        start = None
        for _ in range(20):
            r = ik.solve(random_pose(rng), seed_q=Q_HOME, timeout=0.05, max_solutions=1)
            if r.ok and not cm.in_collision(r.solutions[0])[0]:
                start = r.solutions[0]
                break
        for _ in range(20):
            goal = random_pose(rng)
            r = ik.solve(goal, seed_q=start, timeout=0.05)
            if start is not None and r.ok and not cm.in_collision(r.solutions[0])[0]:
                return boxes, start, goal


class GroundTruth:
    """pybullet scene with the Panda (meshes), the boxes and a table slab, for rendering and
    for the independent collision check."""

    TABLE_TOP_Z = 0.0  # the slab's top; the boxes stand on it

    def __init__(self):
        self.p = BulletClient(connection_mode=pb.DIRECT)
        self.robot = self.p.loadURDF(panda_urdf_path(), useFixedBase=True)
        info = [self.p.getJointInfo(self.robot, i) for i in range(self.p.getNumJoints(self.robot))]
        self.joint = {j[1].decode(): j[0] for j in info}
        self.link = {j[12].decode(): j[0] for j in info}
        col = self.p.createCollisionShape(pb.GEOM_BOX, halfExtents=[1.0, 1.0, 0.05])
        vis = self.p.createVisualShape(pb.GEOM_BOX, halfExtents=[1.0, 1.0, 0.05], rgbaColor=[0.6, 0.5, 0.4, 1])
        self.table = self.p.createMultiBody(0, col, vis, basePosition=[0.5, 0, -0.05])
        self.boxes = []

    def set_boxes(self, boxes):
        for b in self.boxes:
            self.p.removeBody(b)
        self.boxes = []
        for b in boxes:
            col = self.p.createCollisionShape(pb.GEOM_BOX, halfExtents=b.half_extents.tolist())
            vis = self.p.createVisualShape(pb.GEOM_BOX, halfExtents=b.half_extents.tolist(), rgbaColor=[0.2, 0.4, 0.8, 1])
            q = Rotation.from_matrix(b.pose[:3, :3]).as_quat()
            self.boxes.append(self.p.createMultiBody(0, col, vis, basePosition=b.pose[:3, 3].tolist(), baseOrientation=q.tolist()))

    def set_q(self, q):
        for n, v in zip(ARM_JOINTS, q):
            self.p.resetJointState(self.robot, self.joint[n], float(v))
        for n in FINGER_JOINTS:
            self.p.resetJointState(self.robot, self.joint[n], 0.04)

    def cloud(self, q, cfgs):
        self.set_q(q)
        hand = self.p.getLinkState(self.robot, self.link[HAND_LINK], computeForwardKinematics=True)
        T_hand = np.eye(4)
        T_hand[:3, :3] = Rotation.from_quat(hand[5]).as_matrix()
        T_hand[:3, 3] = hand[4]
        poses = {"front": cam.front_camera_pose(), "wrist": T_hand @ cam.wrist_in_hand()}
        rng = np.random.default_rng(0)
        frames = [cam.render(self.p, c, poses[c.name], rng) for c in cfgs]
        views = [DepthView(f.depth, f.K, f.T_world_camera) for f in frames]
        return np.vstack([f.valid_points() for f in frames]), views

    def penetration(self, Q):
        """Deepest robot penetration (m, >0 = collision) into the boxes or the table along Q,
        and where: (sample index, "table" or box index, robot link index)."""
        worst, where = -np.inf, None
        for k, q in enumerate(Q):
            self.set_q(q)
            for j, body in enumerate(self.boxes + [self.table]):
                for c in self.p.getClosestPoints(self.robot, body, 0.0):
                    if body == self.table and c[3] in (-1, 0):  # the base sits on the table
                        continue
                    if -c[8] > worst:
                        worst, where = -c[8], (k, "table" if body == self.table else j, c[3])
        return worst, where


def run_mode(mode, problems, kin, ik, cm, gt, planner, cfgs, timeout, occlusion=True, tag=""):
    rows = []
    for i, (boxes, start, goal) in enumerate(problems):
        gt.set_boxes(boxes)
        if mode == "scene":
            cm.set_boxes(boxes)
            cm.set_point_cloud(np.empty((0, 3)))
            n_pts, prep = 0, 0.0
        else:
            cm.set_boxes([], as_obstacles=False)
            pts, views = gt.cloud(start, cfgs)  # rendering is the sim's cost, not the planner's
            t = time.perf_counter()
            n_pts = cm.set_point_cloud(pts, self_filter_q=start, fill_below=True,
                                       views=views if occlusion else ())
            prep = time.perf_counter() - t
        t = time.perf_counter()
        res = planner.plan(start, goal, Mode.TRANSIT, timeout=timeout)
        wall = time.perf_counter() - t
        row = {"i": i, "status": res.status.name, "time": wall, "points": n_pts, "cloud_prep_time": prep}
        if res.ok:
            P = res.trajectory.positions
            dense = np.vstack([cm.motion_samples(a, b, step=0.005) for a, b in zip(P[:-1], P[1:])])
            pen, where = gt.penetration(dense)
            ee = kin.fk_batch(res.joint_path)[:, :3, 3]
            row.update(joint_path_length=float(np.linalg.norm(np.diff(res.joint_path, axis=0), axis=1).sum()),
                       ee_waypoint_path_length=float(np.linalg.norm(np.diff(ee, axis=0), axis=1).sum()),
                       duration=res.trajectory.duration, waypoints=len(res.joint_path),
                       penetration_m=pen, collision_free=bool(pen <= 0.0),
                       timings=res.timings)
            if pen > 0:
                row.update(hit_where=where, hit_q=dense[where[0]].tolist(),
                           joint_path=res.joint_path.tolist(), segments=res.segments)
        else:
            row["message"] = res.message
        rows.append(row)
        print(f"[{tag}{mode}] {i:3d} {row['status']:18s} {wall * 1e3:7.1f} ms "
              f"{'' if not res.ok else ('free' if row['collision_free'] else 'HIT %.4f' % pen)}", flush=True)
    return rows


def summarize(rows) -> dict:
    """Success, timing (successful plans), path quality and ground-truth collisions over `rows`."""
    ok = [r for r in rows if r["status"] == "SUCCESS"]
    t_ok = np.array([r["time"] for r in ok]) if ok else np.array([np.nan])
    pen = [r["penetration_m"] for r in ok]
    return {
        "problems": len(rows),
        "success_rate": len(ok) / len(rows),
        "status_counts": {s: sum(r["status"] == s for r in rows) for s in sorted({r["status"] for r in rows})},
        "time_median_s": float(np.median(t_ok)), "time_p95_s": float(np.percentile(t_ok, 95)),
        "time_all_median_s": float(np.median([r["time"] for r in rows])),
        "joint_path_length_median_rad": float(np.median([r["joint_path_length"] for r in ok])) if ok else None,
        "ee_path_length_median_m": float(np.median([r["ee_waypoint_path_length"] for r in ok])) if ok else None,
        "trajectory_duration_median_s": float(np.median([r["duration"] for r in ok])) if ok else None,
        "collision_free_fraction": float(np.mean([r["collision_free"] for r in ok])) if ok else None,
        "colliding_plans": int(sum(not r["collision_free"] for r in ok)),
        # deepest ground-truth penetration of a returned plan (m); 0.0 = no contact at all
        "worst_penetration_m": float(max([0.0] + [p for p in pen if p > 0])),
        "cloud_points_median": float(np.median([r["points"] for r in rows])),
        "cloud_prep_median_s": float(np.median([r["cloud_prep_time"] for r in rows])),
        "cloud_prep_p95_s": float(np.percentile([r["cloud_prep_time"] for r in rows], 95)),
    }


def parse_seeds(text: str) -> list[int]:
    """"0,3,7" or "0-4" (inclusive) or a mix."""
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


def run_seed(seed, args, kin, cm, gt, cfgs) -> dict:
    """One seed's suite: problems from rng(seed), IK rng `seed`, planner seed `seed + 1`."""
    ik = IKSolver(kin, rng=seed)
    planner = MotionPlanner(kin, ik, cm, seed=seed + 1)
    rng = np.random.default_rng(seed)
    n_boxes = (args.min_boxes, args.max_boxes)
    problems = [make_problem(rng, kin, ik, cm, n_boxes) for _ in range(args.problems)]
    return {m: run_mode(m, problems, kin, ik, cm, gt, planner, cfgs, args.timeout,
                        occlusion=not args.no_occlusion, tag=f"seed {seed} ")
            for m in args.modes.split(",")}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="20 problems")
    ap.add_argument("--problems", type=int, default=100, help="problems per seed")
    ap.add_argument("--seed", type=int, default=0, help="one seed (ignored with --seeds)")
    ap.add_argument("--seeds", default=None, help='several seeds: "0-4" or "0,5,9"')
    ap.add_argument("--timeout", type=float, default=5.0)
    ap.add_argument("--camera-px", type=int, default=128, help="camera width = height (sim default 128)")
    ap.add_argument("--modes", default="scene,point_cloud")
    ap.add_argument("--min-boxes", type=int, default=4)
    ap.add_argument("--max-boxes", type=int, default=8)
    ap.add_argument("--no-occlusion", action="store_true",
                    help="point cloud without the hidden-space fill (the model before issue 19)")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "planning.json"))
    args = ap.parse_args()
    if args.quick:
        args.problems = 20
    seeds = parse_seeds(args.seeds) if args.seeds else [args.seed]
    kin = PandaKinematics()
    cm = CollisionModel(kin, table_z=GroundTruth.TABLE_TOP_Z)  # the bench's own table (below)
    gt = GroundTruth()
    cfgs = (cam.CameraConfig("front", args.camera_px, args.camera_px),
            cam.CameraConfig("wrist", args.camera_px, args.camera_px))
    per_seed = {s: run_seed(s, args, kin, cm, gt, cfgs) for s in seeds}
    results = {}
    for m in args.modes.split(","):
        rows = [dict(r, seed=s) for s in seeds for r in per_seed[s][m]]
        results[m] = summarize(rows)
        results[m]["per_seed"] = {str(s): {k: v for k, v in summarize(per_seed[s][m]).items()
                                           if k in ("success_rate", "status_counts", "colliding_plans",
                                                    "worst_penetration_m", "time_median_s", "time_p95_s")}
                                  for s in seeds}
        results[m]["rows"] = rows
    out = {
        "benchmark": "planning", "command": "python " + " ".join(sys.argv),
        "problems": args.problems * len(seeds), "problems_per_seed": args.problems, "seeds": seeds,
        "occlusion": not args.no_occlusion,
        "boxes_per_problem": [args.min_boxes, args.max_boxes], "timeout_s": args.timeout, "camera_px": args.camera_px,
        "machine": machine_info(),
        "anchors": {"moveit_ompl_rrtconnect_typical_s": [0.1, 0.2], "curobo_gpu_median_s": 0.031,
                    "vamp_simd_median_s": 35e-6},
        "results": results,
    }
    for m, r in results.items():
        print(m, json.dumps({k: v for k, v in r.items() if k != "rows"}, indent=1))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()

"""Kinematic reachability of every reset region by our Panda (robosuite's mounting, core/robot.py).

For N reset samples per (task, variant) it asks IK (core/planning IKSolver, joint limits, no
collision check) for the EE poses a top-down solution needs:
- grasp: above the grasp point (8 cm) and at it, for each symmetric grasp yaw (scripted.grasp_pose's
  handle / carton top), reachable if one yaw reaches both;
- place: the object at its goal through that grasp: a nut's ring 5 cm above its peg top and at the
  release height (any of the peg's symmetric nut yaws), the milk 8 cm above the bin floor and at the
  drop height, the needle tip 5 cm before the ring and its shaft centre at the ring (either direction),
  a Three Piece Assembly piece 4 cm above its seat and at the release height (piece 1 in the base at any
  of the base's four yaws; piece 2 on piece 1 seated in the base, the same four yaws).
A sample counts as reachable if every skill has a reachable option. This is the arm's kinematics
only: the physics may still fail (see bench/datagen), and it says nothing about the path.

    python bench/reachability/run.py [--samples 200] [--tasks ThreePieceAssembly] [--out bench/results/reachability.json]

With --tasks, the other tasks' rows already in --out are kept.
"""
from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
from bench.machine import machine_info  # noqa: E402

from skillgen_ros.core.geometry import Pose  # noqa: E402
from skillgen_ros.core.planning.ik import IKSolver  # noqa: E402
from skillgen_ros.core.planning.kinematics import PandaKinematics  # noqa: E402
from skillgen_ros.core.robot import Q_HOME, TABLE_Z  # noqa: E402
from skillgen_ros.core.tasks import TASK_NAMES, get_task  # noqa: E402
from skillgen_ros.core.tasks.scripted import (LID_PUSH_FROM, LID_PUSH_TO, LID_PUSH_Z, POD_RELEASE_IN,  # noqa: E402
                                               ScriptParams, grasp_pose, nearest_equivalent, object_yaw, top_down)
from skillgen_ros.core.demonstrator.human_like import PIECE_DROP, PIECE_GRASP_DEPTH  # noqa: E402

PRM = ScriptParams()
PAIRS = {"Square": [("square_nut", "square_peg")], "NutAssembly": [("square_nut", "square_peg"),
                                                                   ("round_nut", "round_peg")],
         "PickPlace": [("milk", "bin")], "Threading": [("needle", "tripod")],
         "ThreePieceAssembly": [("piece_1", "base"), ("piece_2", "piece_1")],
         "Coffee": [("coffee_pod", "coffee_machine")]}
PIECE_PERIOD = {"piece_1": np.pi, "piece_2": np.pi / 2}   # the ridge; the square knob


class Reach:
    def __init__(self, seed: int = 0):
        self.ik = IKSolver(PandaKinematics(), rng=seed)

    def ok(self, poses: list[Pose]) -> bool:
        return all(self.ik.solve(p, seed_q=Q_HOME, max_iterations=60, timeout=1.0).ok for p in poses)


def _yaw(pose: Pose) -> float:
    x = pose.rotation.apply([1.0, 0.0, 0.0])
    return float(np.arctan2(x[1], x[0]))


def grasp_options(obj, pose: Pose, poses: dict | None = None) -> list[Pose]:
    """Top-down grasps at the handle (period pi) or 2.5 cm below the carton top (period pi / 2); Coffee's
    pod at its grasp keypoint, fingers across the machine's x (the scripted solution's two yaws)."""
    if obj.type == "coffee_pod":
        y = object_yaw(poses["coffee_machine"]) + np.pi / 2
        return [grasp_pose(obj, pose, nearest_equivalent(y, k * np.pi, np.pi), PRM) for k in (0, 1)]
    y0 = _yaw(pose)
    if obj.id in PIECE_PERIOD:   # across the piece's x, PIECE_GRASP_DEPTH below its top (the demonstrator's)
        point, period = pose.position + [0.0, 0.0, obj.half_extents[2] - PIECE_GRASP_DEPTH], PIECE_PERIOD[obj.id]
        y0 += np.pi / 2
    elif obj.type == "milk":
        point, period = pose.position + [0.0, 0.0, obj.half_extents[2] - PRM.milk_grasp_depth], np.pi / 2
    else:
        point = pose.rotation.apply(obj.keypoint("handle")) + pose.position + [0.0, 0.0, PRM.grasp_z_offset]
        period = np.pi
    return [top_down(point, y0 + k * period) for k in range(int(round(2 * np.pi / period)))
            if abs(((y0 + k * period + np.pi) % (2 * np.pi)) - np.pi) <= np.radians(170)]


def object_goals(task, obj, target, poses) -> list[list[Pose]]:
    """Per admissible goal yaw, the object poses along the place / insert motion."""
    tp = poses[target.id]
    if obj.id in PIECE_PERIOD:
        base = task.object("base")
        bp = poses["base"]
        seat = TABLE_Z + (obj.half_extents[2] if obj.id == "piece_1" else 2 * base.half_extents[2] + obj.half_extents[2])
        return [[Pose(np.r_[bp.position[:2], z], Rotation.from_euler("z", _yaw(bp) + k * np.pi / 2).as_quat())
                 for z in (seat + 0.04, seat + PIECE_DROP)] for k in range(4)]
    if obj.type in ("square_nut", "round_nut"):
        top = tp.position[2] + target.half_extents[2]
        ring_local = obj.keypoint("ring_center")
        yaws = np.arange(4) * np.pi / 2 + _yaw(tp) if target.symmetry == "z4" else np.arange(8) * np.pi / 4
        out = []
        for y in yaws:
            R = Rotation.from_euler("z", y)
            out.append([Pose(np.r_[tp.position[:2], z] - R.apply(ring_local), R.as_quat())
                        for z in (top + 0.05, TABLE_Z + obj.half_extents[2] + PRM.place_drop)])
        return out
    if obj.type == "coffee_pod":
        top = tp.rotation.apply(target.keypoint("holder_top")) + tp.position
        release = np.r_[top[:2], top[2] - POD_RELEASE_IN + obj.half_extents[2]]
        q = poses[obj.id].quaternion   # carried upright, as grasped
        return [[Pose(release + [0.0, 0.0, 0.03], q), Pose(release, q)]]
    if obj.type == "milk":
        floor = tp.rotation.apply(target.keypoint("floor_center")) + tp.position
        return [[Pose(np.r_[floor[:2], floor[2] + obj.half_extents[2] + h], Rotation.from_euler("z", y).as_quat())
                 for h in (0.08, PRM.place_drop)] for y in (np.arange(4) * np.pi / 2)]
    ring = tp.rotation.apply(target.keypoint("ring_center")) + tp.position
    axis = tp.rotation.apply([1.0, 0.0, 0.0])
    out = []
    for d in (axis, -axis):
        R = Rotation.from_euler("z", np.arctan2(d[1], d[0]))
        out.append([Pose(ring + d * (-PRM.insert_pre) - R.apply(obj.keypoint("tip")), R.as_quat()),
                    Pose(ring - R.apply(obj.keypoint("shaft_center")), R.as_quat())])
    return out


def lid_push_options(poses) -> list[list[Pose]]:
    """Coffee: the scripted push from behind the open lid over its hinge, per top-down hand yaw."""
    m = poses["coffee_machine"]
    out = []
    for k in (0, 1):
        q = top_down(np.zeros(3), object_yaw(m) + k * np.pi).quaternion
        out.append([Pose(m.rotation.apply([0.0, y, z]) + m.position, q)
                    for y, z in ((LID_PUSH_FROM, LID_PUSH_Z + 0.09), (LID_PUSH_FROM, LID_PUSH_Z), (LID_PUSH_TO, LID_PUSH_Z))])
    return out


def sample_reachable(reach: Reach, task, poses) -> dict:
    res = {}
    for obj_id, target_id in PAIRS[task.name]:
        obj, target = task.object(obj_id), task.object(target_id)
        grasps = [g for g in grasp_options(obj, poses[obj_id], poses)
                  if reach.ok([Pose(g.position + [0, 0, PRM.approach_height], g.quaternion), g])]
        res[f"grasp_{obj_id}"] = bool(grasps)
        placed = False
        for g in grasps or grasp_options(obj, poses[obj_id], poses):
            T_obj_ee = poses[obj_id].inverse() @ g
            for goal in object_goals(task, obj, target, poses):
                if reach.ok([o @ T_obj_ee for o in goal]):
                    placed = True
                    break
            if placed:
                break
        res[f"place_{obj_id}"] = placed
    if task.name == "Coffee":
        res["close_lid"] = any(reach.ok(path) for path in lid_push_options(poses))
    res["all"] = all(res.values())
    return res


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--tasks", default=",".join(t for t in TASK_NAMES if t in PAIRS),
                    help="of " + ", ".join(PAIRS) + " (Coffee Prep's reach: bench/datagen/mug_grasp_reach.py)")
    ap.add_argument("--out", default=str(REPO / "bench/results/reachability.json"))
    a = ap.parse_args()
    reach = Reach()
    names = a.tasks.split(",")
    if set(names) - set(PAIRS):
        ap.error(f"no reachability poses for {sorted(set(names) - set(PAIRS))}; known: {', '.join(PAIRS)}")
    old = json.loads(Path(a.out).read_text())["cells"] if Path(a.out).exists() else []
    cells = [c for c in old if c["task"] not in names and c["task"] in TASK_NAMES]
    for name in names:
        task = get_task(name)
        for v in task.variants:
            rows = [sample_reachable(reach, task, task.sample_reset(v, np.random.default_rng(s)))
                    for s in range(a.samples)]
            frac = {k: round(float(np.mean([r[k] for r in rows])), 3) for k in rows[0]}
            cells.append({"task": name, "variant": v, "samples": a.samples, "reachable": frac})
            print(f"{name:12s} {v:11s} " + " ".join(f"{k}={x:.3f}" for k, x in frac.items()), flush=True)
    Path(a.out).write_text(json.dumps({"machine": machine_info(), "cells": cells}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

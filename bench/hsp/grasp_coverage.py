"""bench/hsp/grasp_coverage: were the objects pi failed to grasp outside what its training data covered?

Nut Assembly D1's HSP network (issue 23) never closed the hand on the square nut in 8 of 10 diagnosed
rollouts, where the same network grasped it 10 of 10 on D0's reset scenes
(bench/results/hsp_skill_diagnosis*.json). One explanation is coverage: D1's nut region is wider, so a
test scene could lie where the 1000 training demos hold no nut. This checks it without running the
sim: each diagnosed rollout's object pose is the task's reset sample for its seed
(`TaskSpec.sample_reset`, what the sim builds), and each training demo's is its first recorded
`obs/<object>_pose`. Distance is planar position plus `--yaw-m-per-rad` metres per radian of yaw.
Only runs of networks trained in the dataset's cell folder count. A test scene is as well covered as the data's own demos when its mean distance to its k nearest
training demos lies within the data's own spread of that number (each demo against the others).

    .venv/bin/python bench/hsp/grasp_coverage.py \\
        --dataset out/bench_hsp/NutAssembly_D1/data_hsp_1000/demo.hdf5 \\
        --diagnosis bench/results/hsp_skill_diagnosis.json bench/results/hsp_skill_diagnosis_d1_net_on_d0.json \\
        --run-contains NutAssembly step_013500
"""
from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path

import h5py
import numpy as np
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.hsp.retrain import record  # noqa: E402
from bench.machine import machine_info  # noqa: E402


def planar(pose) -> np.ndarray:
    """(x, y, yaw) of a 7-vector x y z qx qy qz qw."""
    pose = np.asarray(pose, dtype=float)
    return np.array([pose[0], pose[1], Rotation.from_quat(pose[3:7]).as_euler("xyz")[2]])


def distances(p: np.ndarray, pts: np.ndarray, yaw_m_per_rad: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Planar distance, absolute yaw difference (rad, wrapped) and their sum in metres, to every row of pts."""
    dxy = np.linalg.norm(pts[:, :2] - p[:2], axis=1)
    dyaw = np.abs((pts[:, 2] - p[2] + np.pi) % (2 * np.pi) - np.pi)
    return dxy, dyaw, dxy + yaw_m_per_rad * dyaw


def training_poses(dataset: Path, obj: str) -> np.ndarray:
    with h5py.File(dataset, "r") as f:
        return np.array([planar(f["data"][n][f"obs/{obj}_pose"][0]) for n in f["data"]])


def coverage(p: np.ndarray, pts: np.ndarray, k: int, yaw_m_per_rad: float, skip_self: bool = False) -> dict:
    dxy, dyaw, d = distances(p, pts, yaw_m_per_rad)
    order = np.argsort(d)[int(skip_self):]
    i = order[0]
    return {"nearest_xy_m": round(float(dxy[i]), 4), "nearest_yaw_deg": round(float(np.degrees(dyaw[i])), 1),
            "mean_k_m": round(float(np.mean(d[order[:k]])), 4)}


def scene_rows(diagnosis: Path, cell_dir: Path, contains: list[str], task: str, obj: str) -> list[dict]:
    """Every diagnosed rollout of the networks trained in cell_dir (the dataset's cell) whose run key
    holds every string in contains: its variant, seed, whether pi closed the hand in skill 0."""
    from skillgen_ros.core.tasks import get_task

    spec = get_task(task)
    rows = []
    for key, run in json.loads(diagnosis.read_text())["runs"].items():
        if Path(run["checkpoint"]).parent.parent != cell_dir or not all(c in key for c in contains):
            continue
        for r in run["rows"]:
            pose = spec.sample_reset(run["variant"], np.random.default_rng(r["reset_seed"]))[obj]
            first = r["skills"]["0"]
            rows.append({"file": diagnosis.name, "run": key, "variant": run["variant"], "reset_seed": r["reset_seed"],
                         "grasped": first.get("closed_steps", 0) > 0, "ended": first["ended"],
                         "pose": planar([*pose.position, *pose.quaternion])})
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dataset", required=True, help="the training data (robomimic-layout HDF5)")
    ap.add_argument("--diagnosis", nargs="+", required=True, help="bench/hsp/skill_diagnosis.py results")
    ap.add_argument("--run-contains", nargs="*", default=[], help="only runs whose key holds every string")
    ap.add_argument("--task", default="NutAssembly")
    ap.add_argument("--object", default="square_nut", help="the object skill 0 grasps")
    ap.add_argument("--k", type=int, default=10)
    ap.add_argument("--yaw-m-per-rad", type=float, default=0.1)
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "hsp_grasp_coverage.json"))
    a = ap.parse_args(argv)
    train = training_poses(Path(a.dataset), a.object)
    own = np.array([coverage(p, train, a.k, a.yaw_m_per_rad, skip_self=True)["mean_k_m"] for p in train])
    rows = []
    for path in a.diagnosis:
        for r in scene_rows(Path(path), Path(a.dataset).parent.parent, a.run_contains, a.task, a.object):
            p = r.pop("pose")
            rows.append({**r, "x": round(float(p[0]), 4), "y": round(float(p[1]), 4),
                         "yaw_deg": round(float(np.degrees(p[2])), 1), **coverage(p, train, a.k, a.yaw_m_per_rad)})
    lo, hi = (float(v) for v in np.percentile(own, [5, 95]))
    summary = {}
    for grasped in (True, False):
        sel = [r["mean_k_m"] for r in rows if r["grasped"] == grasped]
        summary["grasped" if grasped else "not_grasped"] = {
            "scenes": len(sel), "mean_k_m": [round(min(sel), 4), round(max(sel), 4)] if sel else [],
            "outside_own_5_95": sum(not lo <= v <= hi for v in sel)}
    rec = {"dataset": a.dataset, "demos": len(train), "object": a.object, "k": a.k, "yaw_m_per_rad": a.yaw_m_per_rad,
           "training_region": {"x": [round(float(train[:, 0].min()), 3), round(float(train[:, 0].max()), 3)],
                               "y": [round(float(train[:, 1].min()), 3), round(float(train[:, 1].max()), 3)]},
           "own_mean_k_m_5_50_95": [round(float(v), 4) for v in np.percentile(own, [5, 50, 95])],
           "summary": summary, "rows": rows,
           "command": shlex.join([".venv/bin/python", "bench/hsp/grasp_coverage.py", *(argv or sys.argv[1:])])}
    record(Path(a.out), f"{a.task}/{Path(a.dataset).parent.parent.name}/{a.object}", rec, machine_info())
    print(json.dumps({"own_mean_k_m_5_50_95": rec["own_mean_k_m_5_50_95"], **summary}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

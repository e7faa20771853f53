"""Perception benchmark: model-based 6D pose on rendered sim scenes of every task.

For each task, --scenes scenes (200; --quick: 12) spread evenly over its variants (D0, D1, D2 and
clutter where the task has it), seeds 0..N-1, rendered by core.sim at 640x480 with the depth-noise
model on (sigma = a + b z^2, plus dropout). Per object: translation error, symmetry-aware rotation
error, ADD-S, and whether the estimate landed on a different object (wrong identity), at 640x480
and at the sim camera's default resolution for the task (TaskSpec.camera_size: 128x128, Threading
480x360). Latency: per frame CPU and wall time of
estimate_poses with OMP/BLAS threads pinned to 1, recorded in the accuracy pass (pool workers
compete for the cores) and in a separate single-process pass of 25 scenes per task
(latency_single_process; the latency goal is judged on this one). Truth is SimWorld.object_poses() (the objects' mesh frames).

Baseline, measured in the same run on every --baseline-every'th scene: the textbook open3d pipeline
(FPFH + RANSAC global registration, then 6-DOF point-to-plane ICP; no upright prior, no yaw sweep,
no visibility). Ratios ours/baseline are reported for median errors and latency.

    python bench/perception/run.py [--quick] [--scenes N] [--workers K]

Writes bench/results/perception.json (with the rerun command and machine info).
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")  # one core per frame, as the goal states

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
from bench.machine import machine_info  # noqa: E402
GOALS = {"adds_lt_1cm_rate": 0.95, "trans_median_mm": 5.0, "rot_median_deg": 3.0, "latency_640x480_ms": 100.0}

_W = {}  # per-worker state


def _init(noise: tuple[float, float, float]):
    from skillgen_ros.core.sim import SimWorld
    from skillgen_ros.core.sim.camera import CameraConfig
    a, b, drop = noise
    hi = CameraConfig("front", 640, 480, noise_base=a, noise_quadratic=b, dropout=drop)
    lo = CameraConfig("front", 0, 0, noise_base=a, noise_quadratic=b, dropout=drop)  # 0 x 0: the task's size
    _W["world"] = SimWorld(cameras=(hi,))
    _W["cams"] = {"hi": hi, "default": lo}
    import open3d as o3d
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)


def _camera(name: str, task: str):
    """The pass's camera for `task`: 640x480, or the sim's default for that task (its camera_size)."""
    from skillgen_ros.core.tasks import get_task
    return _W["cams"][name].sized(get_task(task).camera_size)


def _evaluate(res, truth: dict, models: dict) -> list[dict]:
    from skillgen_ros.core.perception import metrics
    rows = []
    for oid, m in models.items():
        G = truth[oid]
        row = {"id": oid, "found": oid in res.poses}
        if row["found"]:
            T = res.poses[oid].pose.matrix()
            own = np.linalg.norm(T[:3, 3] - G[:3, 3])
            others = [np.linalg.norm(T[:3, 3] - truth[k][:3, 3]) for k in truth if k != oid]
            row.update(trans=float(own), rot=float(np.degrees(metrics.rotation_error(T[:3, :3], G[:3, :3], m.symmetry))),
                       adds=metrics.add_s(m.points, T, G), wrong_id=bool(others and min(others) < own),
                       confidence=float(res.poses[oid].confidence))
        rows.append(row)
    return rows


def _reset_models(spec) -> dict:
    """Models of the objects a reset's look must find: not those hidden then (Coffee Prep's pod in its drawer)."""
    from skillgen_ros.core.perception.models import models_for_objects
    seen = spec.required_ids([o.id for o in spec.objects], 0)
    return models_for_objects([o for o in spec.objects if o.id in seen])


def _scene(job: tuple) -> dict:
    from skillgen_ros.core.perception.pipeline import PerceptionParams, estimate_poses
    from skillgen_ros.core.perception.pose import PoseParams
    from skillgen_ros.core.sim.camera import FRONT_EYE
    from skillgen_ros.core.tasks import get_task
    task, variant, seed, with_baseline = job
    w = _W["world"]
    w.reset(task, variant, seed)
    truth = {k: p.matrix() for k, p in w.object_poses().items()}  # object (mesh) frames
    models = _reset_models(get_task(task))
    params = PerceptionParams()
    out = {"task": task, "variant": variant, "seed": seed}
    for name in ("hi", "default"):
        w.cameras["front"] = _camera(name, task)  # same camera pose, other resolution
        pts = w.render("front").points_world
        estimate_poses(pts, models, params, FRONT_EYE) if seed == 0 else None  # warm caches (grids)
        c, t = time.process_time(), time.perf_counter()
        res = estimate_poses(pts, models, params, FRONT_EYE)
        out[name] = {"latency": time.perf_counter() - t, "cpu": time.process_time() - c, "status": res.status.name,
                     "objects": _evaluate(res, truth, models), "timings": res.timings}
        if name == "hi":  # best of 2 wall times: the frame's cost with other load partly filtered out
            reps = []
            for _ in range(1):
                t = time.perf_counter()
                estimate_poses(pts, models, params, FRONT_EYE)
                reps.append(time.perf_counter() - t)
            out[name]["best2"] = min([out[name]["latency"]] + reps)
        if name == "hi" and with_baseline:
            base = replace(params, pose=PoseParams(upright=False, global_registration=True), accept_score=0.2)
            c, t = time.process_time(), time.perf_counter()
            res_b = estimate_poses(pts, models, base, None)
            out["baseline"] = {"latency": time.perf_counter() - t, "cpu": time.process_time() - c,
                               "status": res_b.status.name,
                               "objects": _evaluate(res_b, truth, models)}
    return out


def _latency(task: str, n: int, noise) -> dict:
    """Per-frame latency of estimate_poses in this process alone (no pool workers competing for
    the cores): n scenes of `task` at 640x480 and at the default resolution, CPU and wall time."""
    from skillgen_ros.core.perception.pipeline import PerceptionParams, estimate_poses
    from skillgen_ros.core.sim.camera import FRONT_EYE
    from skillgen_ros.core.tasks import get_task
    if "world" not in _W:
        _init(noise)
    w, spec = _W["world"], get_task(task)
    models, params = _reset_models(spec), PerceptionParams()
    out = {}
    for name in ("hi", "default"):
        w.cameras["front"] = _camera(name, task)
        cpu, wall = [], []
        for i in range(n):
            w.reset(task, spec.variants[i % len(spec.variants)], 10_000 + i)
            pts = w.render("front").points_world
            c, t = time.process_time(), time.perf_counter()
            estimate_poses(pts, models, params, FRONT_EYE)
            cpu.append(time.process_time() - c)
            wall.append(time.perf_counter() - t)
        out[name] = {"frames": n, "cpu_median_ms": float(np.median(cpu) * 1000),
                     "cpu_p95_ms": float(np.percentile(cpu, 95) * 1000),
                     "wall_median_ms": float(np.median(wall) * 1000), "wall_p95_ms": float(np.percentile(wall, 95) * 1000)}
    return out


def _stats(frames: list[dict], key: str) -> dict:
    objs = [o for f in frames if key in f for o in f[key]["objects"]]
    found = [o for o in objs if o["found"]]
    lat = np.array([f[key]["latency"] for f in frames if key in f]) * 1000
    cpu = np.array([f[key]["cpu"] for f in frames if key in f]) * 1000
    if not objs:
        return {}
    arr = lambda k: np.array([o[k] for o in found]) if found else np.array([np.nan])  # noqa: E731
    tr, rot, adds = arr("trans") * 1000, arr("rot"), arr("adds") * 1000
    n = len(objs)
    out = {
        "frames": len(lat), "objects": n, "found_rate": len(found) / n,
        "trans_median_mm": float(np.median(tr)), "trans_p95_mm": float(np.percentile(tr, 95)),
        "rot_median_deg": float(np.median(rot)), "rot_p95_deg": float(np.percentile(rot, 95)),
        "adds_median_mm": float(np.median(adds)),
        # missing objects count as failures of ADD-S < 1 cm
        "adds_lt_1cm_rate": float(sum(o["adds"] < 0.01 for o in found) / n),
        "wrong_identity_rate": float(sum(o["wrong_id"] for o in found) / n),
        "status_ok_rate": float(np.mean([f[key]["status"] == "OK" for f in frames if key in f])),
        "latency_median_ms": float(np.median(lat)), "latency_p95_ms": float(np.percentile(lat, 95)),
        # CPU time of the frame on its one thread: the "one core" cost, insensitive to other load
        "cpu_median_ms": float(np.median(cpu)), "cpu_p95_ms": float(np.percentile(cpu, 95)),
    }
    best2 = [f[key]["best2"] for f in frames if key in f and "best2" in f[key]]
    if best2:
        out["best_of_2_median_ms"] = float(np.median(best2) * 1000)
        out["best_of_2_p95_ms"] = float(np.percentile(best2, 95) * 1000)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="12 scenes per task")
    ap.add_argument("--scenes", type=int, default=None, help="scenes per task (default 200)")
    ap.add_argument("--workers", type=int, default=max(1, (os.cpu_count() or 2) - 1))
    ap.add_argument("--noise", type=float, nargs=3, default=(0.001, 0.0015, 0.002),
                    metavar=("A", "B", "DROPOUT"), help="depth noise sigma = A + B z^2 (m), pixel dropout")
    ap.add_argument("--baseline-every", type=int, default=10, help="run the baseline on every k-th scene")
    ap.add_argument("--out", default=str(REPO / "bench" / "results" / "perception.json"))
    args = ap.parse_args(argv)
    n = args.scenes or (12 if args.quick else 200)

    from skillgen_ros.core.tasks import TASK_NAMES, get_task
    jobs = []
    for task in TASK_NAMES:
        variants = get_task(task).variants
        jobs += [(task, variants[i % len(variants)], i, i % args.baseline_every == 0) for i in range(n)]
    t0 = time.time()
    with ProcessPoolExecutor(args.workers, initializer=_init, initargs=(tuple(args.noise),)) as ex:
        frames = list(ex.map(_scene, jobs, chunksize=4))
    wall = time.time() - t0
    lat_n = 6 if args.quick else 25
    latency = {task: _latency(task, lat_n, tuple(args.noise)) for task in TASK_NAMES}
    lat_all = {k: float(np.median([latency[t][res][k] for t in TASK_NAMES]))
               for res in ("hi",) for k in ("cpu_median_ms", "wall_median_ms")}

    report = {"overall": {k: _stats(frames, k) for k in ("hi", "default", "baseline")}, "per_task": {}, "per_variant": {}}
    for task in TASK_NAMES:
        fr = [f for f in frames if f["task"] == task]
        report["per_task"][task] = {k: _stats(fr, k) for k in ("hi", "default", "baseline")}
        for v in get_task(task).variants:
            report["per_variant"][f"{task}/{v}"] = _stats([f for f in fr if f["variant"] == v], "hi")
    hi, base = report["overall"]["hi"], report["overall"]["baseline"]
    # Baseline ratios on the same scenes only.
    same = [f for f in frames if "baseline" in f]
    ours_same = _stats(same, "hi")
    ratios = {k: (ours_same[k] / base[k] if base.get(k) else None)
              for k in ("trans_median_mm", "rot_median_deg", "latency_median_ms", "cpu_median_ms")} if base else {}
    ratios.update({"adds_lt_1cm_rate": ours_same["adds_lt_1cm_rate"] / base["adds_lt_1cm_rate"]
                   if base and base["adds_lt_1cm_rate"] else None})
    goals = {
        "adds_lt_1cm_rate": {"goal": GOALS["adds_lt_1cm_rate"], "value": hi["adds_lt_1cm_rate"]},
        "trans_median_mm": {"goal": GOALS["trans_median_mm"], "value": hi["trans_median_mm"]},
        "rot_median_deg": {"goal": GOALS["rot_median_deg"], "value": hi["rot_median_deg"]},
        "latency_640x480_ms": {"goal": GOALS["latency_640x480_ms"], "value": lat_all["wall_median_ms"],
                               "measure": "median over tasks of the median wall time per frame, one process, "
                                          "one thread (latency_single_process)"},
    }
    for k, g in goals.items():
        g["met"] = bool(g["value"] >= g["goal"]) if k == "adds_lt_1cm_rate" else bool(g["value"] <= g["goal"])
    phases = {}
    for f in frames:
        for k, v in f["hi"]["timings"].items():
            phases.setdefault(k, []).append(v * 1000)
    out = {
        "benchmark": "perception",
        "command": " ".join(["python", "bench/perception/run.py"] + (argv if argv is not None else sys.argv[1:])),
        "machine": machine_info(threads_per_frame=os.environ.get("OMP_NUM_THREADS")),
        "config": {"scenes_per_task": n, "tasks": list(TASK_NAMES), "resolution_hi": [640, 480],
                   "resolution_default": {t: list(get_task(t).camera_size) for t in TASK_NAMES},
                   "depth_noise_sigma": "a + b z^2",
                   "noise_a_m": args.noise[0], "noise_b_per_m": args.noise[1], "dropout": args.noise[2],
                   "baseline": "open3d FPFH+RANSAC + 6-DOF point-to-plane ICP, every "
                               f"{args.baseline_every}th scene", "workers": args.workers, "wall_s": wall},
        "goals": goals,
        "ratios_ours_over_baseline": ratios,
        "latency_single_process": latency,
        "phase_median_ms_640x480": {k: float(np.median(v)) for k, v in phases.items()},
        **report,
        "failures": [{"task": f["task"], "variant": f["variant"], "seed": f["seed"], "status": f["hi"]["status"],
                      "bad": [o for o in f["hi"]["objects"] if not o["found"] or o["adds"] >= 0.01]}
                     for f in frames if f["hi"]["status"] != "OK"
                     or any(not o["found"] or o["adds"] >= 0.01 for o in f["hi"]["objects"])][:50],
    }
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=1))
    print(json.dumps({"goals": goals, "ratios_ours_over_baseline": ratios, "latency_single_process": latency,
                      "overall_640x480": hi, "overall_default_res": report["overall"]["default"],
                      "baseline": base}, indent=1))
    print(f"wrote {args.out} ({len(frames)} scenes, {wall:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

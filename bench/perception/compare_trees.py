"""Paired perception check of two code trees (e.g. main and a change): accuracy on the same rendered scenes
and CPU time per frame, each tree in its own process (PYTHONPATH), run back to back.

Accuracy: --scenes scenes a task spread over its variants (seeds 0..N-1), at 640x480 and the sim camera's
default resolution, with bench/perception/run.py's noise: objects found, ADD-S < 1 cm, rotation errors
over 90 deg (a half-turn). CPU: the median process time of estimate_poses per 640x480 frame over
--latency-scenes D0 scenes of --latency-tasks, the trees alternating twice (the VM's speed drifts).

    .venv/bin/python bench/perception/compare_trees.py --old /path/to/main --new . \
        --out bench/results/perception_compare.json
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.machine import machine_info  # noqa: E402

_CHILD = r'''
import json, os, sys, time
import numpy as np
sys.path.insert(0, os.path.join(sys.argv[1], "bench", "perception"))
import run as B
from skillgen_ros.core.perception.pipeline import PerceptionParams, estimate_poses
from skillgen_ros.core.sim.camera import FRONT_EYE
from skillgen_ros.core.tasks import get_task
mode, tasks, n = sys.argv[2], sys.argv[3].split(","), int(sys.argv[4])
B._init((0.001, 0.0015, 0.002))
w, out = B._W["world"], {}
for task in tasks:
    spec = get_task(task)
    rows, cpu = {"hi": [], "default": []}, []
    for i in range(n):
        w.reset(task, spec.variants[0] if mode == "cpu" else spec.variants[i % len(spec.variants)], i)
        truth, models = {k: p.matrix() for k, p in w.object_poses().items()}, B._reset_models(spec)
        for name in (("hi",) if mode == "cpu" else ("hi", "default")):
            # trees before 2026-12-06 render every task's default pass at 128x128 (no B._camera)
            w.cameras["front"] = B._camera(name, task) if hasattr(B, "_camera") else B._W["cams"][name]
            pts = w.render("front").points_world
            if mode == "cpu" and i == 0:
                estimate_poses(pts, models, PerceptionParams(), FRONT_EYE)  # warm the models' caches
            c = time.process_time()
            r = estimate_poses(pts, models, PerceptionParams(), FRONT_EYE)
            cpu.append(time.process_time() - c)
            rows[name] += B._evaluate(r, truth, models)
    out[task] = {"cpu_median_ms": float(np.median(cpu) * 1000)} if mode == "cpu" else {
        k: {"objects": len(v), "found": sum(x["found"] for x in v),
            "adds_lt_1cm": sum(x["found"] and x["adds"] < 0.01 for x in v) / len(v),
            "rot_over_90deg": sum(x["found"] and x["rot"] > 90 for x in v)} for k, v in rows.items()}
print("RESULT " + json.dumps(out))
'''


def _child(tree: str, mode: str, tasks: list[str], n: int) -> dict:
    env = {**os.environ, "PYTHONPATH": str(Path(tree).resolve()), "OMP_NUM_THREADS": "1"}
    p = subprocess.run([sys.executable, "-c", _CHILD, str(Path(tree).resolve()), mode, ",".join(tasks), str(n)],
                       env=env, capture_output=True, text=True, cwd="/", check=True)
    return json.loads(next(line for line in p.stdout.splitlines() if line.startswith("RESULT "))[7:])


def _revision(tree: str) -> str:
    """The tree's commit, with "+dirty" when it has uncommitted changes."""
    rev = subprocess.run(["git", "-C", tree, "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
    dirty = subprocess.run(["git", "-C", tree, "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True).stdout.strip()
    return rev + ("+dirty" if dirty else "")


def main(argv=None) -> int:
    from skillgen_ros.core.tasks import TASK_NAMES

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--old", required=True)
    ap.add_argument("--new", required=True)
    ap.add_argument("--tasks", nargs="+", default=list(TASK_NAMES))
    ap.add_argument("--scenes", type=int, default=8)
    ap.add_argument("--latency-tasks", nargs="+", default=["Square", "Coffee", "CoffeePreparation"])
    ap.add_argument("--latency-scenes", type=int, default=6)
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "perception_compare.json"))
    a = ap.parse_args(argv)
    t0 = time.time()
    trees = (("old", a.old), ("new", a.new))
    acc = {name: _child(tree, "accuracy", a.tasks, a.scenes) for name, tree in trees}
    cpu = [{name: _child(tree, "cpu", a.latency_tasks, a.latency_scenes) for name, tree in trees} for _ in range(2)]
    ratio = {t: [c["new"][t]["cpu_median_ms"] / c["old"][t]["cpu_median_ms"] for c in cpu] for t in a.latency_tasks}
    out = {"benchmark": "perception_compare",
           "command": " ".join(["python", "bench/perception/compare_trees.py",
                                *(argv if argv is not None else sys.argv[1:])]),
           "machine": machine_info(threads_per_frame="1"), "measured": time.strftime("%Y-%m-%d"),
           "trees": {name: {"path": str(Path(tree).resolve()), "revision": _revision(tree)} for name, tree in trees},
           "scenes_per_task": a.scenes, "accuracy": acc, "cpu_pairs": cpu, "cpu_ratio_new_to_old": ratio,
           "wall_seconds": time.time() - t0}
    Path(a.out).write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps({"accuracy": acc, "cpu_ratio_new_to_old": ratio}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

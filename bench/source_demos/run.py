"""Open-loop replay of every shipped source demo through SimWorld, from its recorded initial scene.

For each bag in bags/<task>/ (listed in subsets.yaml): reset the pybullet SimWorld with the
recorded (task, variant, seed), send the recorded osc_target stream (pose + gripper) one control
period per command, and check the task's success predicate. Goal: >= 9/10 per task.
Baseline, same run: the same command streams replayed in a *different* D0 scene (seed + 500),
i.e. plain open-loop replay without SkillGen's object-centric adaptation.

    python bench/source_demos/run.py [--quick] [--bags bags] [--out bench/results/source_demos.json]
--quick replays the 3-demo subset of each task only; --tasks T [T ...] replays only those tasks and keeps
the other tasks' results already in --out.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
from bench.machine import machine_info  # noqa: E402

from skillgen_ros.cli.demos import subset_paths  # noqa: E402
from skillgen_ros.core.geometry import Pose  # noqa: E402
from skillgen_ros.core.sim import SimWorld  # noqa: E402
from skillgen_ros.core.skills.bag_demos import open_bag, read_demo_arrays, read_scene  # noqa: E402
from skillgen_ros.core.tasks import TASK_NAMES  # noqa: E402


SHIFT = 500  # scene-seed offset of the baseline's different scene


def replay(world: SimWorld, arrays, task: str, variant: str, seed: int) -> bool:
    world.reset(task, variant, seed)
    for p, q, g in zip(arrays.action_positions, arrays.action_quaternions, arrays.gripper):
        world.step(Pose(p, q), float(g))
    return bool(world.task_success())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="only the 3-demo subset per task")
    ap.add_argument("--bags", default=str(REPO / "bags"))
    ap.add_argument("--out", default=str(REPO / "bench/results/source_demos.json"))
    ap.add_argument("--tasks", nargs="+", default=list(TASK_NAMES), choices=TASK_NAMES)
    a = ap.parse_args()
    world = SimWorld()
    old = json.loads(Path(a.out).read_text()).get("tasks", {}) if Path(a.out).exists() else {}
    results = {t: r for t, r in old.items() if t not in a.tasks and t in TASK_NAMES}
    t_all = time.monotonic()
    for task in a.tasks:
        paths = subset_paths(Path(a.bags) / task, "first3" if a.quick else "all")
        rows = []
        for path in paths:
            reader = open_bag(path)
            scene = read_scene(reader)
            arrays = read_demo_arrays(path, reader)
            t0 = time.monotonic()
            ok = replay(world, arrays, scene.task, scene.variant, scene.seed)
            dt = time.monotonic() - t0
            base = replay(world, arrays, scene.task, scene.variant, scene.seed + SHIFT)
            rows.append({"demo": path.name, "seed": scene.seed, "steps": len(arrays.timestamps),
                         "success": ok, "baseline_other_scene_success": base, "replay_s": round(dt, 2)})
            print(f"{task:12s} {path.name}: replay {'OK ' if ok else 'FAIL'}  other-scene replay "
                  f"{'OK' if base else 'fail'}  ({dt:.1f} s)", flush=True)
        n = len(rows)
        succ = sum(r["success"] for r in rows)
        base = sum(r["baseline_other_scene_success"] for r in rows)
        results[task] = {"demos": n, "successes": succ, "rate": succ / n, "goal_met": succ >= 0.9 * n,
                         "baseline_other_scene_successes": base, "baseline_rate": base / n,
                         "ratio_vs_baseline": (succ / base) if base else None, "per_demo": rows}
        print(f"{task}: {succ}/{n} open-loop replays succeed (baseline, other scene: {base}/{n})")
    results = {t: results[t] for t in TASK_NAMES if t in results}  # the task list's order, however many reran
    doc = {"benchmark": "source_demos", "command": "python bench/source_demos/run.py" + (" --quick" if a.quick else "")
           + ("" if list(a.tasks) == list(TASK_NAMES) else " --tasks " + " ".join(a.tasks)),
           "what": "open-loop replay of the shipped source demos from their recorded initial scenes (pybullet)",
           "machine": machine_info(),
           "wall_s": round(time.monotonic() - t_all, 1), "tasks": results}
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(doc, indent=2) + "\n")
    print(f"wrote {a.out}")
    return 0 if all(r["goal_met"] for r in results.values()) else 1


if __name__ == "__main__":
    sys.exit(main())

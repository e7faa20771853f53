"""bench/datagen/source_skills.py: where each task's source skills start and what the hand does in them.

Initiation augmentation perturbs a skill's first pose by up to 8 cm and 80 deg, so how far that pose is from
where the gripper acts (closes on a grasp, opens on a release) decides how often a perturbed start is in
collision or leads the skill astray; the wrist's turn within a skill decides whether a rigidly replayed skill
stays inside panda_joint7's range when its object is turned (Coffee D2, docs/tasks.md). Per task and skill,
median over the shipped source demos (bags/<task>): the distance from the initiation to the first gripper
change, its height part, the steps in between, and the hand's yaw sweep over the whole skill (the heading of
the hand's x axis in the object's x-y plane, unwrapped; a turn about the vertical for a top-down hand).
Reads the bags only; no simulation.

    .venv/bin/python bench/datagen/source_skills.py [--tasks Square Coffee ...]

Writes bench/results/source_skills.json.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.machine import machine_info  # noqa: E402

OUT = ROOT / "bench" / "results" / "source_skills.json"
TASKS = ("Square", "NutAssembly", "Threading", "ThreePieceAssembly", "Coffee", "CoffeePreparation")


def skill_geometry(segment) -> dict[str, float]:
    """One source skill segment: initiation -> first gripper change (distance, height, steps) and yaw sweep."""
    E = np.asarray(segment.ee_poses_in_object)
    g = np.asarray(segment.gripper)
    changed = np.flatnonzero(g != g[0])
    k = int(changed[0]) if changed.size else len(E) - 1
    heading = np.unwrap(np.arctan2(E[:, 1, 0], E[:, 0, 0]))  # the hand's x axis in the object's x-y plane
    return {"to_gripper_change_m": float(np.linalg.norm(E[0, :3, 3] - E[k, :3, 3])),
            "height_above_m": float(E[0, 2, 3] - E[k, 2, 3]), "steps_to_gripper_change": k,
            "yaw_sweep_deg": float(np.degrees(heading.max() - heading.min()))}


def task_rows(task: str) -> dict[str, dict]:
    from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos
    from skillgen_ros.core.tasks import get_task

    spec = get_task(task)
    demos = load_source_demos(expand_bag_paths([str(ROOT / "bags" / task)]), spec)
    out = {}
    for sk in spec.skills:
        per = [skill_geometry(d.skill(sk.index)) for d in demos]
        out[sk.name] = {k: float(np.median([p[k] for p in per])) for k in per[0]}
        out[sk.name]["yaw_sweep_deg_range"] = [float(min(p["yaw_sweep_deg"] for p in per)),
                                               float(max(p["yaw_sweep_deg"] for p in per))]
        out[sk.name]["demos"] = len(per)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tasks", nargs="+", default=list(TASKS))
    a = ap.parse_args(argv)
    doc = {"benchmark": "source_skills", "command": ".venv/bin/python bench/datagen/source_skills.py "
           + " ".join(["--tasks", *a.tasks]), "machine": machine_info(), "tasks": {}}
    for task in a.tasks:
        doc["tasks"][task] = task_rows(task)
        for name, r in doc["tasks"][task].items():
            print(f"{task} {name}: initiation {r['to_gripper_change_m'] * 100:.1f} cm from the gripper change "
                  f"({r['height_above_m'] * 100:.1f} cm above, {r['steps_to_gripper_change']:.0f} steps), "
                  f"yaw sweep {r['yaw_sweep_deg']:.0f} deg", flush=True)
    OUT.write_text(json.dumps(doc, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""bench/datagen/mug_grasp_reach.py: which pitched mug grasps Coffee Prep's scene admits, and which ones the
demonstrator's placement admits.

Coffee Prep D2 falls short of the paper (36.5% vs 59.9) on IK_FAILED at the transit to skill 0, the mug grasp
(docs/coffee_prep.md). The demonstrator grasps the mug across its body, the hand pitched 45 deg
(core/tasks/scripted_coffee_prep.py side_pose), approaching at `rel` from straight opposite the handle. For
each reset this asks the paper profile's planner (SimGenerationEnv, extras off, ground-truth poses, from the
reset's arm configuration) for the transit to the pre-grasp (8 cm back along the hand) at `rel` in 15 deg steps
and both pitch signs, and separately which `rel` the demonstrator's placement allows: some placement approach
within MUG_APPROACH_SLACK keeps the pitched hand's EE yaw within MUG_GRASP_MAX_YAW at the grasp and MUG_MAX_YAW
at the placement (_mug_plan's constraints).

    .venv/bin/python bench/datagen/mug_grasp_reach.py [--variants D0 D2] [--seeds 30]

Writes bench/results/coffee_prep_mug_grasp.json.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.machine import machine_info  # noqa: E402

OUT = ROOT / "bench" / "results" / "coffee_prep_mug_grasp.json"
RELS = np.arange(-90, 91, 15)


def placement_allows(S, rel: float, mug0, machine) -> bool:
    """_mug_plan's EE-yaw bounds (mug_yaws_allowed): some placement approach and pitch sign keep the wrist in range."""
    from skillgen_ros.core.tasks.scripted import object_yaw

    a = object_yaw(mug0) + np.pi / 2 + rel
    inward = object_yaw(machine) - np.pi / 2 + S.MUG_APPROACH_TURN
    return any(S.mug_yaws_allowed(a, q, sign) for sign in (1, -1)
               for q in inward + np.linspace(-S.MUG_APPROACH_SLACK, S.MUG_APPROACH_SLACK, 37))


def run_variant(env, variant: str, seeds: int) -> dict:
    from skillgen_ros.core.geometry import Pose
    from skillgen_ros.core.planning.planner import Mode, PlanStatus
    from skillgen_ros.core.tasks import scripted_coffee_prep as S
    from skillgen_ros.core.tasks.scripted import object_yaw

    reach = {f"{r}/{s}": 0 for r in RELS for s in (1, -1)}
    allowed, chosen = {int(r): 0 for r in RELS}, []
    for seed in range(seeds):
        sc = env.reset("CoffeePreparation", variant, seed)
        poses = env.world.object_poses()
        g, m = poses["mug"], poses["coffee_machine"]
        mug = next(o for o in sc.objects if o.id == "mug")
        handle = object_yaw(g) + np.pi / 2
        point = g.rotation.apply(mug.keypoint("grasp")) + g.position
        a, _q, _sign = S._mug_plan(g, m)
        chosen.append(round(float(np.degrees(S._wrap(a - handle)))))
        q0 = env.world.joint_positions()
        env.set_skill_object("mug")
        env._planning_scene("mug", None)  # the collision world the attempt's transit to skill 0 plans in
        for r in RELS:
            allowed[int(r)] += placement_allows(S, np.radians(r), g, m)
            for sign in (1, -1):
                goal = S.side_pose(point, handle + np.radians(r), sign)
                pre = Pose(goal.position - goal.rotation.apply([0.0, 0.0, 0.08]), goal.quaternion)
                res = env.planner.plan(q0, pre, Mode.TRANSIT, manipulated="mug", timeout=5.0, extras=False)
                reach[f"{r}/{sign}"] += res.status is PlanStatus.SUCCESS
    return {"seeds": seeds, "demonstrator_rel_deg": sorted(set(chosen)),
            "reachable_by_rel_and_sign": {k: v / seeds for k, v in reach.items()},
            "placement_allows_by_rel": {str(k): v / seeds for k, v in allowed.items()}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", nargs="+", default=["D0", "D2"])
    ap.add_argument("--seeds", type=int, default=30)
    a = ap.parse_args(argv)
    from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv

    env = SimGenerationEnv(SimEnvConfig(perception="ground_truth"))
    env.set_planner_extras(False)  # the paper profile's planner
    t = time.perf_counter()
    out = {"benchmark": "coffee_prep_mug_grasp", "rel_deg": [int(r) for r in RELS],
           "command": "python bench/datagen/mug_grasp_reach.py " + " ".join(argv or sys.argv[1:]),
           "variants": {v: run_variant(env, v, a.seeds) for v in a.variants}}
    out["wall_seconds"], out["machine"] = round(time.perf_counter() - t, 1), machine_info()
    env.close()
    OUT.write_text(json.dumps(out, indent=1) + "\n")
    for v, r in out["variants"].items():
        best = {rel: max(r["reachable_by_rel_and_sign"][f"{rel}/{s}"] for s in (1, -1)) for rel in out["rel_deg"]}
        print(v, "demonstrator rel", r["demonstrator_rel_deg"], "| reachable (best sign) by rel:",
              {k: round(x, 2) for k, x in best.items()}, "| placement allows:",
              [k for k, x in r["placement_allows_by_rel"].items() if x == 1.0])
    return 0


if __name__ == "__main__":
    sys.exit(main())

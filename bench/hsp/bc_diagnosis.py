"""bench/hsp/bc_diagnosis: how far the MimicGen BC baseline gets in its rollouts (issue 23: BC scores
~0% where the paper reports 49-91%, a gap to explain before it is reported).

Success alone cannot tell "never reaches the nut" from "carries it but misses the peg". Per rollout
(the benchmark's held-out reset seeds, `mode: bc`, in-process, ground-truth object poses) this
records the EE's closest approach to the nut's reset position, how far the nut moved, how high it
ended, and its final x-y distance to the peg. The result goes to --out with the command that reruns it.

    .venv/bin/python bench/hsp/bc_diagnosis.py \\
        --checkpoint out/bench_hsp/Square_D2/net_bc_1000/step_013500.pt --variant D2 --rollouts 10
"""
from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.hsp.diagnosis import diagnose_rollouts  # noqa: E402
from bench.machine import machine_info  # noqa: E402

REACHED, MOVED, LIFTED = 0.03, 0.02, 0.03  # m: EE within 3 cm of the nut; nut moved 2 cm; nut 3 cm up at the end


def rollout_row(env, policy, spec, seed: int, variant: str) -> dict:
    """One BC rollout and where it left the task's manipulated object."""
    from skillgen_ros.core.deploy.rollout import DeployConfig, run_rollout

    obj, target = spec.skills[0].object_id, spec.skills[-1].object_id
    env.reset(spec.name, variant, seed)  # the same reset run_rollout makes: read the start poses
    start = env.world.object_poses()
    o0, peg = start[obj].position.copy(), start[target].position.copy()
    r = run_rollout(env, policy, spec, seed, variant, DeployConfig(mode="bc"))
    o1 = env.world.object_poses()[obj].position
    d = np.linalg.norm(r.ee_trajectory[:, :3] - o0, axis=1)
    return {"reset_seed": seed, "success": r.success, "reason": r.reason.value, "steps": r.steps,
            "ee_min_to_object_m": round(float(d.min()), 3), "step_closest": int(d.argmin()),
            "object_moved_m": round(float(np.linalg.norm(o1[:2] - o0[:2])), 3),
            "object_lift_end_m": round(float(o1[2] - o0[2]), 3),
            "object_to_target_xy_end_m": round(float(np.linalg.norm(o1[:2] - peg[:2])), 3)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--checkpoint", required=True)
    ap.add_argument("--variant", default="D2")
    ap.add_argument("--rollouts", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0, help="evaluation seed (rollout_seed(seed, i), as bench/hsp/run.py)")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "hsp_bc_diagnosis.json"))
    a = ap.parse_args(argv)
    _, spec, rows = diagnose_rollouts(a.checkpoint, a.seed, a.rollouts,
                                      lambda env, policy, spec: lambda seed: rollout_row(env, policy, spec, seed,
                                                                                         a.variant))
    n = len(rows)
    summary = {"rollouts": n, "successes": sum(r["success"] for r in rows),
               f"reached_within_{REACHED}m": sum(r["ee_min_to_object_m"] < REACHED for r in rows),
               f"object_moved_over_{MOVED}m": sum(r["object_moved_m"] > MOVED for r in rows),
               f"object_lifted_over_{LIFTED}m_at_end": sum(r["object_lift_end_m"] > LIFTED for r in rows),
               "object_off_table": sum(r["object_lift_end_m"] < -0.5 for r in rows)}
    out = {"checkpoint": a.checkpoint, "task": spec.name, "variant": a.variant, "summary": summary, "rows": rows,
           "machine": machine_info(), "command": "python bench/hsp/bc_diagnosis.py " + shlex.join(argv or sys.argv[1:])}
    Path(a.out).write_text(json.dumps(out, indent=2))
    print(json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())

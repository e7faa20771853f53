"""bench/hsp/skill_diagnosis: where each skill of an HSP rollout leaves its object (issue 23: Nut
Assembly D0 scored 0-16% at 9k steps where Square D0, whose square nut and peg are the same, scored
78% with HSP-TAMP; a gap to explain before it is reported).

Success and the skill endings in bench/results/hsp.json cannot tell "the nut rests on the peg's top"
from "the nut fell beside the peg" or "pi never closed on the second nut". Per rollout (the
benchmark's held-out reset seeds, in-process, ground-truth object poses) this follows every skill:
- a transit (grasp) skill: the hand's closest approach to the object and how many steps pi
  commanded the hand closed;
- a transfer onto a peg: where the held nut ended against robosuite's on_peg rule
  (core/tasks/suite.py): `seated` (on the peg), `on_top` (centred within 3 cm but above the
  seated height: resting on the peg's top), `beside` (off by 3 cm or more), with the hand's
  distance from the nut.
The result goes to --out under the checkpoint and mode, with the command that reruns it.

    .venv/bin/python bench/hsp/skill_diagnosis.py \\
        --checkpoint out/bench_hsp/NutAssembly_D0/net_hsp_1000/step_013500.pt --mode tamp --rollouts 10
"""
from __future__ import annotations

import argparse
import shlex
import sys
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.hsp.diagnosis import diagnose_rollouts  # noqa: E402
from bench.hsp.retrain import record  # noqa: E402
from bench.machine import machine_info  # noqa: E402


def placement(xy_off_m: float, z_above_table_m: float) -> str:
    """robosuite on_peg's two conditions, named by which one fails (suite.ON_PEG_XY, ON_PEG_Z)."""
    from skillgen_ros.core.tasks import suite

    if xy_off_m >= suite.ON_PEG_XY:
        return "beside"
    return "seated" if z_above_table_m < suite.ON_PEG_Z else "on_top"


class SkillTracer:
    """Wraps env.step: per control step of a policy skill, the quantities above."""

    def __init__(self, env, spec):
        self.env, self.spec, self.skill = env, spec, -1
        self.trace: dict[int, list[tuple]] = {}
        self._step = env.step
        env.step = self.step

    def progress(self, skill: int, stage: str, steps: int) -> None:
        self.skill = skill

    def step(self, target, g):
        from skillgen_ros.core.deploy.rollout import true_object_poses
        from skillgen_ros.core.tasks import suite

        o = self._step(target, g)
        s = next((k for k in self.spec.skills if k.index == self.skill), None)
        if s is None:
            return o
        poses, ee = true_object_poses(self.env), np.asarray(o.ee_pose[:3], float)
        held = s.attached_object if s.mode == "transfer" and s.attached_object else s.object_id
        c = suite.keypoint_world(self.spec.object(held), poses[held], "body_origin")
        row = (float(np.linalg.norm(ee - c)), float(g), float(np.sum(o.gripper)))
        if s.mode == "transfer" and "peg" in self.spec.object(s.object_id).type:
            p = suite.keypoint_world(self.spec.object(s.object_id), poses[s.object_id], "body_origin")
            row += (float(np.max(np.abs(c[:2] - p[:2]))), float(c[2] - suite.TABLE_Z))
        self.trace.setdefault(self.skill, []).append(row)
        return o


def skill_rows(tracer: SkillTracer, result) -> dict:
    out = {}
    for log in result.skills:
        a = np.array(tracer.trace.get(log.skill_index, []))
        row = {"ended": log.ended, "policy_steps": log.policy_steps}
        if len(a):
            row.update(hand_min_m=round(float(a[:, 0].min()), 3), hand_end_m=round(float(a[-1, 0]), 3),
                       closed_steps=int((a[:, 1] > 0).sum()))
            if a.shape[1] == 5:
                row.update(xy_off_end_m=round(float(a[-1, 3]), 3), z_end_m=round(float(a[-1, 4]), 3),
                           placement=placement(a[-1, 3], a[-1, 4]))
        out[str(log.skill_index)] = row
    return out


def summarize(rows: list[dict]) -> dict:
    skills = sorted({k for r in rows for k in r["skills"]}, key=int)
    return {"rollouts": len(rows), "successes": sum(r["success"] for r in rows),
            "reasons": dict(Counter(r["reason"] for r in rows)),
            "skills": {k: {"ended": dict(Counter(r["skills"][k]["ended"] for r in rows if k in r["skills"])),
                           "placement": dict(Counter(r["skills"][k]["placement"] for r in rows
                                                     if "placement" in r["skills"].get(k, {}))),
                           "never_closed": sum(r["skills"][k].get("closed_steps", 1) == 0 for r in rows
                                               if k in r["skills"])}
                       for k in skills}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--checkpoint", required=True)
    ap.add_argument("--mode", default="tamp", choices=["tamp", "class", "reg"])
    ap.add_argument("--variant", default="", help="the checkpoint's own when empty")
    ap.add_argument("--rollouts", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0, help="evaluation seed (rollout_seed(seed, i), as bench/hsp/run.py)")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "hsp_skill_diagnosis.json"))
    a = ap.parse_args(argv)
    from skillgen_ros.core.deploy.loading import load_demos
    from skillgen_ros.core.deploy.rollout import DeployConfig, run_rollout

    variant = a.variant

    def make_row(env, policy, spec):
        nonlocal variant
        variant = variant or policy.config.variant
        demos = load_demos(spec.name) if a.mode in ("class", "tamp") else []
        tracer = SkillTracer(env, spec)

        def row(seed: int) -> dict:
            tracer.trace.clear()
            r = run_rollout(env, policy, spec, seed, variant, DeployConfig(mode=a.mode), demos,
                            on_progress=tracer.progress)
            return {"reset_seed": seed, "success": r.success, "reason": r.reason.value, "message": r.message,
                    "skills": skill_rows(tracer, r)}
        return row

    _, spec, rows = diagnose_rollouts(a.checkpoint, a.seed, a.rollouts, make_row)
    rec = {"checkpoint": a.checkpoint, "mode": a.mode, "variant": variant, "summary": summarize(rows), "rows": rows,
           "command": shlex.join([".venv/bin/python", "bench/hsp/skill_diagnosis.py", *(argv or sys.argv[1:])])}
    record(Path(a.out), f"{spec.name}/{variant}/{Path(a.checkpoint).stem}/{a.mode}/seed{a.seed}", rec, machine_info())
    print(rec["summary"], flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

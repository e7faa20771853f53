"""bench/hsp/retrain_termination: train T (with the HSP-Class head it shares a trunk with) again on a
trained checkpoint under another label rule, and evaluate HSP-Class and HSP-Reg on it (issue 23: why
T rarely fires at the end of a grasp).

T is retrained alone (bench/hsp/retrain.py); pi and I stay as they were. `--labels settled` is our
option (core/learning/termination.py, docs/hsp.md), `--labels paper` the control retrained the same
way. Each method gets `--rollouts` rollouts on the held-out reset seeds of `--seed`, the seeds the
benchmark (bench/hsp/run.py, seed 0) evaluated the checkpoint's own T on, so the two compare paired.
Results go to --out under the cell, step, rule and seed, with the command that reruns it.

    .venv/bin/python bench/hsp/retrain_termination.py \\
        --checkpoint out/bench_hsp/Threading_D0/net_hsp_1000/step_013500.pt --labels settled
"""
from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.hsp.retrain import (evaluation_record, record, rerun_command, retrain_network,  # noqa: E402
                               retrain_parser)
from bench.machine import machine_info  # noqa: E402

MODES = {"HSP-Class": "class", "HSP-Reg": "reg"}


def main(argv=None) -> int:
    from skillgen_ros.core.learning.config import TERMINATION_LABEL_RULES

    p = retrain_parser(__doc__, "T", str(ROOT / "bench" / "results" / "hsp_termination_labels.json"))
    p.add_argument("--labels", choices=TERMINATION_LABEL_RULES, default="settled")
    p.add_argument("--methods", nargs="+", choices=sorted(MODES), default=["HSP-Class", "HSP-Reg"])
    a = p.parse_args(argv)
    from skillgen_ros.core.deploy import evaluate
    from skillgen_ros.core.learning.checkpoint import load_hsp, read_checkpoint

    src = read_checkpoint(a.checkpoint)[0]
    if not src.has_termination:
        raise SystemExit(f"{a.checkpoint} has no termination classifier")
    cfg = dataclasses.replace(src, train=dataclasses.replace(src.train, termination_labels=a.labels))
    new = Path(a.checkpoint).with_name(f"term_{a.labels}_{Path(a.checkpoint).stem}.pt")
    rec = {"checkpoint": a.checkpoint, "checkpoint_step": int(src.step), "labels": a.labels, "seed": a.seed,
           **retrain_network(a.checkpoint, cfg, "termination", str(new), int(a.steps or src.step), a.seed),
           "evaluations": {}}
    key = f"{src.task}/{src.variant}/step{src.step}/{a.labels}/seed{a.seed}"
    rec["command"] = rerun_command("bench/hsp/retrain_termination.py", argv)
    policy = load_hsp(str(new), expect_task=src.task)
    for m in a.methods:
        t = time.time()
        s = evaluate(str(new), src.task, src.variant, MODES[m], a.rollouts, a.seed, policy=policy)
        rec["evaluations"][m] = evaluation_record(s, time.time() - t)
        print(f"{src.task} {src.variant} {m}, T on {a.labels} labels ({rec['steps']} steps): {s.line()}", flush=True)
        record(Path(a.out), key, rec, machine_info())
    return 0


if __name__ == "__main__":
    sys.exit(main())

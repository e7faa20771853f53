"""bench/hsp/retrain_reg: train HSP-Reg's I again on a trained checkpoint, with another target, and
evaluate HSP-Reg on it (issue 23: which target I learns).

I is retrained alone (bench/hsp/retrain.py: what the joint run would have given it). The new
checkpoint keeps pi and T as they were, records `train.reg_target` and the refitted target normalization, and is evaluated with
`--rollouts` HSP-Reg rollouts on the held-out reset seeds. The result goes to --out under the cell
and target, with the command that reruns it.

    .venv/bin/python bench/hsp/retrain_reg.py --checkpoint out/bench_hsp/Square_D1/net_hsp_1000/last.pt \\
        --target nominal --out bench/results/hsp_reg_target.json
    # the control: the stored (perturbed) labels, retrained the same way
    .venv/bin/python bench/hsp/retrain_reg.py --checkpoint ... --target initiation_target
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


def retrain(checkpoint: str, target: str, out_path: str, steps: int | None, seed: int):
    """Train a fresh I on `target` for `steps` (the checkpoint's own by default); write the new checkpoint."""
    from skillgen_ros.core.learning.checkpoint import read_checkpoint
    from skillgen_ros.core.learning.data import fit_initiation_norm, read_demos

    cfg = read_checkpoint(checkpoint)[0]
    if not cfg.has_reg:
        raise SystemExit(f"{checkpoint} has no HSP-Reg network")
    norm = fit_initiation_norm(read_demos(cfg.dataset_path, cfg.train_demos, cfg.obs_keys), target)
    cfg = dataclasses.replace(cfg, train=dataclasses.replace(cfg.train, reg_target=target), initiation_norm=norm)
    return retrain_network(checkpoint, cfg, "initiation", out_path, int(steps or cfg.step), seed)


def main(argv=None) -> int:
    from skillgen_ros.core.learning.config import REG_TARGETS

    p = retrain_parser(__doc__, "I", str(ROOT / "bench" / "results" / "hsp_reg_target.json"))
    p.add_argument("--target", choices=REG_TARGETS, default="nominal")
    a = p.parse_args(argv)
    from skillgen_ros.core.deploy import evaluate
    from skillgen_ros.core.learning.checkpoint import read_checkpoint

    src = read_checkpoint(a.checkpoint)[0]
    new = Path(a.checkpoint).with_name(f"reg_{a.target}_{Path(a.checkpoint).stem}.pt")
    rec = {"checkpoint": a.checkpoint, "checkpoint_step": int(src.step), "target": a.target, "seed": a.seed,
           **retrain(a.checkpoint, a.target, str(new), a.steps, a.seed)}
    t = time.time()
    s = evaluate(str(new), src.task, src.variant, "reg", a.rollouts, a.seed)
    rec.update(evaluation=evaluation_record(s, time.time() - t), command=rerun_command("bench/hsp/retrain_reg.py", argv))
    print(f"{src.task} {src.variant} HSP-Reg, I on {a.target} ({rec['steps']} steps, {rec['train_seconds']:.0f} s): "
          f"{s.line()}", flush=True)
    record(Path(a.out), f"{src.task}/{src.variant}/step{src.step}/{a.target}/seed{a.seed}", rec, machine_info())
    return 0


if __name__ == "__main__":
    sys.exit(main())

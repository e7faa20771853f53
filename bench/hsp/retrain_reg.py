"""bench/hsp/retrain_reg: train HSP-Reg's I again on a trained checkpoint, with another target, and
evaluate HSP-Reg on it (issue 23: which target I learns).

pi, T and I are separate networks with their own encoders, Adams and batches (core/learning/
trainer.py), so retraining I alone for the checkpoint's own number of steps is what the joint run
would have given it, at a few minutes instead of hours. The new checkpoint keeps pi and T as they
were, records `train.reg_target` and the refitted target normalization, and is evaluated with
`--rollouts` HSP-Reg rollouts on the held-out reset seeds. The result goes to --out under the cell
and target, with the command that reruns it.

    .venv/bin/python bench/hsp/retrain_reg.py --checkpoint out/bench_hsp/Square_D1/net_hsp_1000/last.pt \\
        --target nominal --out bench/results/hsp_reg_target.json
    # the control: the stored (perturbed) labels, retrained the same way
    .venv/bin/python bench/hsp/retrain_reg.py --checkpoint ... --target initiation_target
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shlex
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.machine import machine_info  # noqa: E402


def retrain(checkpoint: str, target: str, out_path: str, steps: int | None, seed: int):
    """Train a fresh I on `target` for `steps` (the checkpoint's own by default); write the new checkpoint."""
    import torch

    from skillgen_ros.core.learning.checkpoint import load_networks, read_checkpoint, save_checkpoint
    from skillgen_ros.core.learning.data import fit_initiation_norm, read_demos
    from skillgen_ros.core.learning.networks import build_networks
    from skillgen_ros.core.learning.trainer import _datasets, _initiation_losses

    cfg, sds, _ = read_checkpoint(checkpoint)
    if not cfg.has_reg:
        raise SystemExit(f"{checkpoint} has no HSP-Reg network")
    steps = int(steps or cfg.step)
    norm = fit_initiation_norm(read_demos(cfg.dataset_path, cfg.train_demos, cfg.obs_keys), target)
    cfg = dataclasses.replace(cfg, train=dataclasses.replace(cfg.train, reg_target=target), initiation_norm=norm)
    data, valid = _datasets(cfg)
    torch.manual_seed(seed)
    torch.set_num_threads(1)
    nets = load_networks(cfg, sds, where=checkpoint)
    nets["initiation"] = build_networks(cfg)["initiation"]
    opt = torch.optim.Adam(nets["initiation"].parameters(), lr=cfg.train.lr)
    only = {"initiation": nets["initiation"]}
    t0, losses = time.time(), []
    for step in range(steps):
        loss = _initiation_losses(cfg, only, data, np.random.default_rng([seed, step]), "cpu")["initiation"]
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        losses.append(float(loss.detach()))
    seconds = time.time() - t0
    nets["initiation"].eval()
    with torch.no_grad():
        v = _initiation_losses(cfg, only, valid, np.random.default_rng([seed, 2**31]), "cpu") if valid else {}
    save_checkpoint(out_path, cfg, nets)
    return {"steps": steps, "train_seconds": seconds, "train_loss_last_epoch": float(np.mean(losses[-100:])),
            "valid_loss": float(v["initiation"]) if v else None}


def main(argv=None) -> int:
    from skillgen_ros.core.learning.config import REG_TARGETS

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--checkpoint", required=True)
    p.add_argument("--target", choices=REG_TARGETS, default="nominal")
    p.add_argument("--steps", type=int, default=0, help="I's training steps (0: the checkpoint's own)")
    p.add_argument("--seed", type=int, default=0, help="I's initial weights and batches, and the evaluation seed")
    p.add_argument("--rollouts", type=int, default=50)
    p.add_argument("--out", default=str(ROOT / "bench" / "results" / "hsp_reg_target.json"))
    a = p.parse_args(argv)
    from skillgen_ros.core.deploy import evaluate
    from skillgen_ros.core.learning.checkpoint import read_checkpoint

    src = read_checkpoint(a.checkpoint)[0]
    new = Path(a.checkpoint).with_name(f"reg_{a.target}_{Path(a.checkpoint).stem}.pt")
    rec = {"checkpoint": a.checkpoint, "checkpoint_step": int(src.step), "target": a.target, "seed": a.seed,
           **retrain(a.checkpoint, a.target, str(new), a.steps, a.seed)}
    t = time.time()
    s = evaluate(str(new), src.task, src.variant, "reg", a.rollouts, a.seed)
    rec.update(evaluation={k: v for k, v in s.to_json().items() if k != "reset_seeds"}, eval_seconds=time.time() - t,
               command=shlex.join([".venv/bin/python", "bench/hsp/retrain_reg.py", *(argv or sys.argv[1:])]))
    print(f"{src.task} {src.variant} HSP-Reg, I on {a.target} ({rec['steps']} steps, {rec['train_seconds']:.0f} s): "
          f"{s.line()}", flush=True)
    out = Path(a.out)
    data = json.loads(out.read_text()) if out.exists() else {}
    data["machine"] = machine_info()
    data.setdefault("runs", {})[f"{src.task}/{src.variant}/step{src.step}/{a.target}/seed{a.seed}"] = rec
    tmp = out.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2))
    os.replace(tmp, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

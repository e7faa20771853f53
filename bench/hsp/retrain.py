"""Train one of a checkpoint's networks again, the others kept (bench/hsp/retrain_reg.py, retrain_termination.py).

pi, T (with the HSP-Class head) and I are separate networks with their own encoders, Adams and
batches (core/learning/trainer.py), so retraining one alone for the checkpoint's own number of
steps is what the joint run would have given it, at minutes instead of hours.
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from pathlib import Path

import numpy as np


def retrain_network(checkpoint: str, cfg, name: str, out_path: str, steps: int, seed: int) -> dict:
    """A fresh `name` network trained on `cfg` (the checkpoint's config with the option under test) for
    `steps`; the other networks are the checkpoint's. Writes the new checkpoint; returns its record."""
    import torch

    from skillgen_ros.core.learning.checkpoint import load_networks, read_checkpoint, save_checkpoint
    from skillgen_ros.core.learning.networks import build_networks
    from skillgen_ros.core.learning.trainer import LOSSES, OPTIMIZED, _datasets

    data, valid = _datasets(cfg)
    torch.manual_seed(seed)
    torch.set_num_threads(1)
    nets = load_networks(cfg, read_checkpoint(checkpoint)[1], where=checkpoint)
    nets[name] = build_networks(cfg)[name]
    opt = torch.optim.Adam(nets[name].parameters(), lr=cfg.train.lr)
    t0, losses = time.time(), []
    for step in range(steps):
        out = LOSSES[name](cfg, nets, data, np.random.default_rng([seed, step]), "cpu")
        loss = sum(v for k, v in out.items() if k in OPTIMIZED)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        losses.append(float(loss.detach()))
    seconds = time.time() - t0
    nets[name].eval()
    with torch.no_grad():
        v = LOSSES[name](cfg, nets, valid, np.random.default_rng([seed, 2**31]), "cpu") if valid else {}
    save_checkpoint(out_path, cfg, nets)
    return {"steps": steps, "train_seconds": seconds, "train_loss_last_epoch": float(np.mean(losses[-100:])),
            "valid": {k: float(x) for k, x in v.items()}}


def retrain_parser(doc: str, network: str, out: str) -> argparse.ArgumentParser:
    """The arguments every retrain script shares; each adds the option it tests."""
    p = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    p.add_argument("--checkpoint", required=True)
    p.add_argument("--steps", type=int, default=0, help=f"{network}'s training steps (0: the checkpoint's own)")
    p.add_argument("--seed", type=int, default=0,
                   help=f"{network}'s initial weights and batches, and the evaluation seed")
    p.add_argument("--rollouts", type=int, default=50)
    p.add_argument("--out", default=out)
    return p


def rerun_command(script: str, argv) -> str:
    """The command that reruns this retrain, for its record."""
    return shlex.join([".venv/bin/python", script, *(argv if argv is not None else sys.argv[1:])])


def evaluation_record(summary, seconds: float) -> dict:
    """An evaluation summary without its (long) seed list, with its wall time."""
    return {**{k: v for k, v in summary.to_json().items() if k != "reset_seeds"}, "eval_seconds": seconds}


def record(out: Path, key: str, rec: dict, machine: dict) -> None:
    """Add one run to a results JSON, atomically."""
    data = json.loads(out.read_text()) if out.exists() else {}
    data["machine"] = machine
    data.setdefault("runs", {})[key] = rec
    tmp = out.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2))
    os.replace(tmp, out)

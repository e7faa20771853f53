"""`skillgen train`: learn a Hybrid Skill Policy (π, T + HSP-Class head, HSP-Reg I) from one dataset.

    skillgen train --dataset out/run/demo.hdf5 --output out/policy            robomimic defaults
    skillgen train --dataset D --output O --resume                             continue after Ctrl-C
    skillgen train --dataset D --output O --epochs 1 --steps-per-epoch 5 --hidden 32 --mlp-hidden 32
                                                                               a tiny checkpoint (tests)

Writes O/last.pt, O/best.pt, O/loss_curves.png. A MimicGen dataset trains the BC-RNN-GMM baseline
on every step (no T, no I). Defaults are robomimic's BC-RNN-GMM (core/learning/config.py); smaller
networks are options and are recorded in the checkpoint.
"""
from __future__ import annotations

import argparse
import json
import logging

from skillgen_ros.core.learning.config import REG_TARGETS, TERMINATION_LABEL_RULES, NetworkConfig, TrainConfig


def _parser() -> argparse.ArgumentParser:
    n, t = NetworkConfig(), TrainConfig()
    p = argparse.ArgumentParser(prog="skillgen train", description=__doc__.split("\n\n")[0])
    p.add_argument("--dataset", required=True, help="generated demo.hdf5")
    p.add_argument("--output", required=True, help="directory for checkpoints and curves")
    p.add_argument("--demos-dir", default="bags", help="<dir>/<task>/ holds the source demos (HSP-Class's classes)")
    p.add_argument("--resume", action="store_true", help="continue from OUTPUT/last.pt")
    p.add_argument("--device", default=t.device, help="cpu (default) or cuda[:N]")
    p.add_argument("--threads", type=int, default=t.threads, help="torch CPU threads (0: torch default)")
    p.add_argument("--epochs", type=int, default=t.epochs)
    p.add_argument("--steps-per-epoch", type=int, default=t.steps_per_epoch)
    p.add_argument("--batch-size", type=int, default=t.batch_size)
    p.add_argument("--lr", type=float, default=t.lr)
    p.add_argument("--seed", type=int, default=t.seed)
    p.add_argument("--valid-ratio", type=float, default=t.valid_ratio)
    p.add_argument("--eval-every", type=int, default=t.eval_every, help="epochs between rollouts (0: never)")
    p.add_argument("--eval-rollouts", type=int, default=t.eval_rollouts, help="rollouts per evaluation")
    p.add_argument("--hidden", type=int, default=n.rnn_hidden, help="LSTM size (robomimic: 400)")
    p.add_argument("--rnn-layers", type=int, default=n.rnn_layers)
    p.add_argument("--mlp-hidden", type=int, nargs="+", default=list(n.mlp_hidden),
                   help="T / Reg MLP (paper: 1024 1024)")
    p.add_argument("--images", action="store_true", help="add front + wrist images (ResNet-18 + spatial softmax)")
    p.add_argument("--all-steps", action="store_true", default=None,
                   help="π on every step (default for MimicGen data)")
    reg = p.add_mutually_exclusive_group()
    reg.add_argument("--reg", dest="reg", action="store_true", default=None, help="train HSP-Reg's I")
    reg.add_argument("--no-reg", dest="reg", action="store_false", help="never train HSP-Reg's I")
    p.add_argument("--reg-target", choices=REG_TARGETS, default=t.reg_target,
                   help="HSP-Reg's target: the initiation before augmentation's perturbation (nominal) or the "
                        "stored, perturbed label")
    p.add_argument("--termination-labels", choices=TERMINATION_LABEL_RULES, default=t.termination_labels,
                   help="T's labels: the paper's (motion steps, first half) or also each skill's still tail (settled)")
    p.add_argument("--stop-after", type=int, default=0, help="stop (as Ctrl-C) after N steps of this invocation")
    p.add_argument("--no-progress", action="store_true")
    return p


def main(argv: list[str]) -> int:
    from skillgen_ros.core.learning.trainer import TrainRequest, train

    a = _parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    net = NetworkConfig(rnn_hidden=a.hidden, rnn_layers=a.rnn_layers, mlp_hidden=tuple(a.mlp_hidden))
    tc = TrainConfig(lr=a.lr, batch_size=a.batch_size, epochs=a.epochs, steps_per_epoch=a.steps_per_epoch,
                     valid_ratio=a.valid_ratio, seed=a.seed, eval_every=a.eval_every, eval_rollouts=a.eval_rollouts,
                     device=a.device, threads=a.threads, reg_target=a.reg_target,
                     termination_labels=a.termination_labels)
    req = TrainRequest(dataset=a.dataset, output_dir=a.output, network=net, train=tc, images=a.images,
                       demos_dir=a.demos_dir, all_steps=a.all_steps, reg=a.reg, resume=a.resume,
                       stop_after=a.stop_after,
                       progress=not a.no_progress)
    r = train(req)
    c = r.config
    print(json.dumps({"last": r.last_path, "best": r.best_path, "step": c.step, "epoch": c.epoch,
                      "finished": r.finished, "best_metric": dict(c.best), "task": c.task, "method": c.method,
                      "heads": {"termination": c.has_termination, "class": c.has_class, "reg": c.has_reg}}, indent=2))
    return 0

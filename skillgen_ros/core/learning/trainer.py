"""Training π, T (+ HSP-Class head) and HSP-Reg's I on one dataset, resumable, robomimic-style.

One loop of global steps; each step updates every network once on its own batch (π: windows,
T/Class and Reg: single steps) with its own Adam. An epoch is `steps_per_epoch` steps; after each
epoch: validation losses, the history record, `last.pt`, `best.pt` when better, and every
`eval_every` epochs the rollout hook `evaluate(checkpoint_path) -> success rate`. Batches at step
k depend only on (seed, k), so an interrupted run resumed from `last.pt` continues exactly where
it stopped. Ctrl-C saves `last.pt` and stops; `stop_after` does the same after N steps.
"""
from __future__ import annotations

import dataclasses
import logging
import shutil
import signal
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import torch
from torch.nn import functional as F

from ..errors import ParameterError
from .checkpoint import check_layout, load_networks, read_checkpoint, resolve_device, save_checkpoint
from .config import HSPConfig, NetworkConfig, TrainConfig
from .data import (TrainingSet, dataset_info, file_sha256, fit_initiation_norm, fit_obs_stats, read_demos,
                   split_train_valid)
from .networks import build_networks
from .observation import IMAGE_KEYS, LOW_DIM_KEYS

log = logging.getLogger("skillgen.train")
LAST, BEST = "last.pt", "best.pt"


@dataclass(frozen=True)
class TrainRequest:
    dataset: str
    output_dir: str
    network: NetworkConfig = NetworkConfig()
    train: TrainConfig = TrainConfig()
    images: bool = False  # add the front and wrist cameras (ResNet-18 + spatial softmax)
    all_steps: bool | None = None  # π on every step; None: when the dataset's method is mimicgen
    reg: bool | None = None  # train HSP-Reg's I; None: when the dataset was generated with augmentation
    demos_dir: str = "bags"  # <dir>/<task>/ holds the source demos generation used: HSP-Class's classes
    num_source_demos: int = 0  # > 0: HSP-Class's classes counted elsewhere (a machine without demos_dir)
    resume: bool = False
    stop_after: int = 0  # > 0: stop (as Ctrl-C would) after this many steps in this invocation
    progress: bool = True


@dataclass(frozen=True)
class TrainResult:
    config: HSPConfig
    last_path: str
    best_path: str
    steps_run: int
    finished: bool


def count_source_demos(demos_dir: str, task: str, seen: int) -> int:
    """HSP-Class predicts an index into the task's source demos (as deployment loads them); `seen`
    (max label + 1 in the dataset) is the fallback when the folder is absent."""
    from ..skills.bag_demos import expand_bag_paths

    folder = Path(demos_dir) / task
    if not folder.is_dir():
        log.warning("no source demos under %s: HSP-Class gets %d classes (the labels seen)", folder, seen)
        return seen
    n = len(expand_bag_paths([folder]))
    if n < seen:
        raise ParameterError(f"{folder} holds {n} source demos, the dataset names demo index {seen - 1}",
                             reason="SOURCE_DEMOS_MISMATCH")
    return n


def _classes(req: TrainRequest, info) -> int:
    """HSP-Class's class count: the request's, else the source demos under demos_dir."""
    if not req.num_source_demos:
        return count_source_demos(req.demos_dir, info.task, info.num_source_demos)
    if req.num_source_demos < info.num_source_demos:
        raise ParameterError(f"num_source_demos {req.num_source_demos} < the dataset's demo index "
                             f"{info.num_source_demos - 1} + 1", reason="SOURCE_DEMOS_MISMATCH")
    return req.num_source_demos


def _new_config(req: TrainRequest) -> HSPConfig:
    info = dataset_info(req.dataset)
    all_steps = info.method == "mimicgen" if req.all_steps is None else req.all_steps
    hsp = info.method != "mimicgen"
    reg = (info.augmented if req.reg is None else req.reg) and hsp
    images = tuple(k for k in IMAGE_KEYS if k in info.obs_shapes) if req.images else ()
    if req.images and len(images) != len(IMAGE_KEYS):
        raise ParameterError(f"--images needs {list(IMAGE_KEYS)} in the dataset, it has {sorted(info.obs_shapes)}",
                             reason="MISSING_IMAGES")
    train, valid = split_train_valid(req.dataset, req.train.valid_ratio, req.train.seed)
    keys = LOW_DIM_KEYS + images
    demos = read_demos(req.dataset, train, keys)
    return HSPConfig(
        task=info.task, variant=info.variant, method=info.method, skills=info.skills, low_dim_keys=LOW_DIM_KEYS,
        image_keys=images, obs_shapes={k: info.obs_shapes[k] for k in keys}, object_ids=info.object_ids,
        num_source_demos=_classes(req, info) if hsp else info.num_source_demos, all_steps=all_steps,
        has_termination=hsp, has_class=hsp, has_reg=reg, obs_stats=fit_obs_stats(demos, LOW_DIM_KEYS),
        initiation_norm=fit_initiation_norm(demos, req.train.reg_target) if reg else None,
        dataset_sha256=file_sha256(req.dataset),
        dataset_path=str(req.dataset), train_demos=train, valid_demos=valid, network=req.network, train=req.train)


def _setup(req: TrainRequest):
    """(config, networks, optimizers, state_dicts of optimizers) for a new or resumed run."""
    out = Path(req.output_dir)
    last = out / LAST
    if req.resume:
        cfg, sds, opt_sds = read_checkpoint(last)
        if cfg.dataset_sha256 != file_sha256(req.dataset):
            raise ParameterError(f"{req.dataset} is not the dataset {last} was trained on (sha256 differs)",
                                 reason="DATASET_CHANGED")
        # a resumed run may train longer and on another device / thread count, nothing else changes
        cfg = dataclasses.replace(cfg, train=dataclasses.replace(
            cfg.train, epochs=max(cfg.train.epochs, req.train.epochs), device=req.train.device,
            threads=req.train.threads))
        nets = load_networks(cfg, sds, where=str(last))
    else:
        if last.exists():
            raise ParameterError(f"{last} exists: pass --resume to continue it, or choose another --output",
                                 reason="OUTPUT_EXISTS")
        out.mkdir(parents=True, exist_ok=True)
        cfg, opt_sds = _new_config(req), {}
        check_layout(cfg, expect_task=cfg.task)
        torch.manual_seed(cfg.train.seed)  # the same initial weights for the same seed
        nets = build_networks(cfg)
    device = resolve_device(cfg.train.device)
    if cfg.train.threads:
        torch.set_num_threads(cfg.train.threads)
    for n in nets.values():
        n.to(device)
    opts = {k: torch.optim.Adam(n.parameters(), lr=cfg.train.lr) for k, n in nets.items()}
    for k, sd in opt_sds.items():
        opts[k].load_state_dict(sd)
    return cfg, nets, opts, device


def _tensor(d: dict[str, np.ndarray], device) -> dict[str, torch.Tensor]:
    return {k: torch.from_numpy(v).to(device) for k, v in d.items()}


def _policy_losses(cfg, nets, data: TrainingSet, rng, device) -> dict[str, torch.Tensor]:
    idx = data.windows(rng.integers(0, len(data.win_start), cfg.train.batch_size))
    act = torch.from_numpy(data.actions[idx]).to(device)
    h = nets["policy"].features(_tensor(data.take(idx), device))
    return {"policy": nets["policy"].head.nll(h, act),
            "policy_mse": F.mse_loss(nets["policy"].head.mode_mean(h), act).detach()}


def _termination_losses(cfg, nets, data: TrainingSet, rng, device) -> dict[str, torch.Tensor]:
    bs = cfg.train.batch_size
    rows = rng.integers(0, data.size, bs)
    tl, _ = nets["termination"](_tensor(data.take(rows), device))
    y = torch.from_numpy(data.term[rows]).to(device)
    out = {"termination": F.cross_entropy(tl, y), "termination_acc": (tl.argmax(-1) == y).float().mean().detach()}
    if cfg.has_class and len(data.init_idx):
        j = rng.integers(0, len(data.init_idx), bs)
        _, cl = nets["termination"](_tensor(data.take(data.init_idx[j]), device))
        y = torch.from_numpy(data.init_cls[j]).to(device)
        out["class"] = F.cross_entropy(cl, y)
        out["class_acc"] = (cl.argmax(-1) == y).float().mean().detach()
    return out


def _initiation_losses(cfg, nets, data: TrainingSet, rng, device) -> dict[str, torch.Tensor]:
    if not len(data.init_idx):
        return {}
    j = rng.integers(0, len(data.init_idx), cfg.train.batch_size)
    return {"initiation": nets["initiation"].loss(_tensor(data.take(data.init_idx[j]), device),
                                                  torch.from_numpy(data.init_tgt[j]).to(device))}


# network -> its batch and losses; the losses it optimizes are the keys without "_acc"/"_mse"
LOSSES = {"policy": _policy_losses, "termination": _termination_losses, "initiation": _initiation_losses}
OPTIMIZED = ("policy", "termination", "class", "initiation")


def _train_step(cfg, nets, opts, data, step: int, device, seconds: dict) -> dict[str, float]:
    """One update of every network; batches depend only on (seed, step)."""
    rng = np.random.default_rng([cfg.train.seed, step])
    torch.manual_seed(cfg.train.seed * 1_000_003 + step)  # pixel shift: same draws after a resume
    out: dict[str, float] = {}
    for name, net in nets.items():
        net.train()
        t0 = time.perf_counter()
        losses = LOSSES[name](cfg, nets, data, rng, device)
        total = sum(v for k, v in losses.items() if k in OPTIMIZED)
        if isinstance(total, torch.Tensor):
            opts[name].zero_grad(set_to_none=True)
            total.backward()
            opts[name].step()
        seconds[name] = seconds.get(name, 0.0) + time.perf_counter() - t0
        out.update({k: float(v.detach()) for k, v in losses.items()})
    return out


@torch.no_grad()
def _validate(cfg, nets, data: TrainingSet | None, device) -> dict[str, float]:
    if data is None:
        return {}
    for n in nets.values():
        n.eval()
    rng = np.random.default_rng([cfg.train.seed, 2**31])  # the same validation batches every epoch
    out = {}
    for name in nets:
        out.update({f"valid_{k}": float(v) for k, v in LOSSES[name](cfg, nets, data, rng, device).items()})
    return out


def _datasets(cfg: HSPConfig) -> tuple[TrainingSet, TrainingSet | None]:
    keys = cfg.obs_keys

    def build(names):
        return TrainingSet(read_demos(cfg.dataset_path, names, keys), cfg.low_dim_keys, cfg.image_keys, cfg.obs_stats,
                           cfg.network.seq_length, cfg.all_steps, cfg.train.initiation_window, cfg.initiation_norm,
                           cfg.train.reg_target, cfg.train.termination_labels)

    return build(cfg.train_demos), (build(cfg.valid_demos) if cfg.valid_demos else None)


def load_evaluate_hook(rollouts: int) -> Callable[[str], object] | None:
    """`skillgen_ros.core.deploy.evaluate(checkpoint_path, rollouts=N)` (in-process rollouts on held-out
    seeds, read as a success rate by float()), if the deployment half is installed."""
    try:
        from ..deploy import evaluate  # noqa: PLC0415 (optional: the deployment half may be absent)
    except ImportError:
        return None
    return lambda path: evaluate(path, rollouts=rollouts)


def _is_better(cfg: HSPConfig, record: dict) -> tuple[str, float, bool] | None:
    """(metric, value, better) for this epoch's record: success rate when it was evaluated, else π's
    validation loss, else its training loss (robomimic keeps both best-validation and best-rollout)."""
    if "success_rate" in record:
        metric, value, higher = "success_rate", record["success_rate"], True
    elif cfg.best.get("metric") == "success_rate":
        return None  # once rollouts rank checkpoints, losses do not
    else:
        metric = "valid_policy" if "valid_policy" in record else "policy"
        value, higher = record[metric], False
    old = cfg.best.get("value") if cfg.best.get("metric") == metric else None
    return metric, value, old is None or (value > old if higher else value < old)


def _end_epoch(cfg: HSPConfig, nets, opts, out: Path, record: dict, evaluate, valid, device) -> HSPConfig:
    """Validate, evaluate (rollouts) when due, rank, and write last.pt (and best.pt when better)."""
    record.update(_validate(cfg, nets, valid, device))
    if evaluate is not None and cfg.train.eval_every and cfg.epoch % cfg.train.eval_every == 0:
        save_checkpoint(out / LAST, dataclasses.replace(cfg, history=cfg.history + (record,)), nets, opts)
        result = evaluate(str(out / LAST))
        record["success_rate"] = float(result)
        if hasattr(result, "wilson_low"):
            record["success_wilson95"] = [float(result.wilson_low), float(result.wilson_high)]
    cfg = dataclasses.replace(cfg, history=cfg.history + (record,))
    ranked = _is_better(cfg, record)
    if ranked and ranked[2]:
        cfg = dataclasses.replace(cfg, best={"metric": ranked[0], "value": ranked[1], "epoch": cfg.epoch,
                                             "step": cfg.step})
    save_checkpoint(out / LAST, cfg, nets, opts)
    if ranked and ranked[2]:
        shutil.copyfile(out / LAST, out / (BEST + ".tmp"))
        (out / (BEST + ".tmp")).replace(out / BEST)
    return cfg


class _StopRequest:
    """Ctrl-C during training stops at the next step boundary (a step is never half applied); a
    second Ctrl-C interrupts at once."""

    def __init__(self):
        self.requested = False
        self._old = None

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self._old = signal.signal(signal.SIGINT, self._handle)
        return self

    def _handle(self, signum, frame):
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True

    def __exit__(self, *exc):
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)
        return False


def train(req: TrainRequest, evaluate: Callable[[str], float] | None = None) -> TrainResult:
    """Train (or resume) until the configured epochs or `stop_after` steps. Ctrl-C saves last.pt at a
    step boundary and raises KeyboardInterrupt."""
    cfg, nets, opts, device = _setup(req)
    data, valid = _datasets(cfg)
    if evaluate is None and cfg.train.eval_every:
        evaluate = load_evaluate_hook(cfg.train.eval_rollouts)
        if evaluate is None:
            log.info("no skillgen_ros.core.deploy.evaluate: evaluation rollouts skipped, best = lowest π loss")
    loop = _Loop(cfg, nets, opts, device, Path(req.output_dir), evaluate)
    with _StopRequest() as stop:
        try:
            loop.run(data, valid, req.stop_after, req.progress, stop)
        except KeyboardInterrupt:
            loop.save_if_unsaved()
            log.warning("interrupted at step %d: saved %s; resume with --resume", loop.cfg.step, loop.out / LAST)
            raise
    loop.save_if_unsaved()  # stopped mid-epoch by stop_after
    c = loop.cfg
    return TrainResult(c, str(loop.out / LAST), str(loop.out / BEST), loop.ran,
                       c.step >= c.train.epochs * c.train.steps_per_epoch)


class _Loop:
    """The step loop's state: config (step, epoch, history, best), networks, per-epoch sums."""

    def __init__(self, cfg, nets, opts, device, out: Path, evaluate):
        self.cfg, self.nets, self.opts, self.device, self.out, self.evaluate = cfg, nets, opts, device, out, evaluate
        self.ran = 0
        self.saved_step = cfg.step

    def save_if_unsaved(self) -> None:
        if self.cfg.step != self.saved_step:
            save_checkpoint(self.out / LAST, self.cfg, self.nets, self.opts)
            self.saved_step = self.cfg.step

    def run(self, data: TrainingSet, valid, stop_after: int, progress: bool, stop: _StopRequest) -> None:
        from tqdm import tqdm

        from .curves import plot_losses

        spe, total = self.cfg.train.steps_per_epoch, self.cfg.train.epochs * self.cfg.train.steps_per_epoch
        sums: dict[str, float] = {}
        seconds: dict[str, float] = {}
        with tqdm(total=total, initial=self.cfg.step, disable=not progress, desc="train", unit="step") as bar:
            while self.cfg.step < total and not (stop_after and self.ran >= stop_after):
                if stop.requested:
                    raise KeyboardInterrupt
                losses = _train_step(self.cfg, self.nets, self.opts, data, self.cfg.step, self.device, seconds)
                self.cfg = dataclasses.replace(self.cfg, step=self.cfg.step + 1)
                self.ran += 1
                for k, v in losses.items():
                    sums[k] = sums.get(k, 0.0) + v
                sums["_n"] = sums.get("_n", 0) + 1
                bar.update(1)
                if self.ran % 10 == 0 or self.cfg.step % spe == 0:
                    bar.set_postfix(loss=f"{losses['policy']:.3f}", epoch=self.cfg.step // spe)
                if self.cfg.step % spe:
                    continue
                n = sums.pop("_n")
                record = {"epoch": self.cfg.step // spe, "step": self.cfg.step, **{k: v / n for k, v in sums.items()},
                          **{f"seconds_{k}": v for k, v in seconds.items()}}
                self.cfg = dataclasses.replace(self.cfg, epoch=self.cfg.step // spe)
                self.cfg = _end_epoch(self.cfg, self.nets, self.opts, self.out, record, self.evaluate, valid,
                                      self.device)
                self.saved_step = self.cfg.step
                if self.cfg.epoch % max(1, self.cfg.train.epochs // 20) == 0 or self.cfg.step >= total:
                    plot_losses(self.cfg.history, self.out / "loss_curves.png")
                sums, seconds = {}, {}

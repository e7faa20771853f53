"""Checkpoints: state_dicts + optimizer states + a JSON config, read with weights_only=True only.

Layout (one torch.save'd dict): {"format": FORMAT, "version": VERSION, "config": JSON string of
HSPConfig, "state_dicts": {net: state_dict}, "optimizers": {net: optimizer state_dict}}. Loading
never unpickles code (LeRobot's rule); every way a file can be wrong is a CheckpointError
(BAD_CHECKPOINT) that says which. Writes go to a temporary file renamed over the target, so an
interrupted save leaves the previous checkpoint intact.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Mapping

import torch

from ..errors import CheckpointError, ParameterError, SkillGenError
from .config import HSPConfig
from .hsp import HybridSkillPolicy
from .networks import build_networks

FORMAT = "skillgen_ros.hsp"
VERSION = 1


def save_checkpoint(path: str | os.PathLike, config: HSPConfig, networks: Mapping[str, torch.nn.Module],
                    optimizers: Mapping[str, torch.optim.Optimizer] | None = None) -> None:
    payload = {"format": FORMAT, "version": VERSION, "config": json.dumps(config.to_json()),
               "state_dicts": {k: {n: t.detach().cpu() for n, t in m.state_dict().items()}
                               for k, m in networks.items()},
               "optimizers": {k: o.state_dict() for k, o in (optimizers or {}).items()}}
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    torch.save(payload, tmp)
    os.replace(tmp, path)


def read_checkpoint(path: str | os.PathLike) -> tuple[HSPConfig, dict, dict]:
    """(config, state_dicts, optimizer states) of a checkpoint file, validated."""
    p = Path(path)
    if not p.is_file():
        raise CheckpointError(f"checkpoint {p} does not exist")
    try:
        payload = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as e:  # truncated zip, random bytes, a pickle that wants code: all refused here
        raise CheckpointError(f"{p} is not a readable checkpoint ({type(e).__name__}: {str(e).splitlines()[0][:200]})")
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise CheckpointError(f"{p} is not a skillgen_ros HSP checkpoint")
    if payload.get("version") != VERSION:
        raise CheckpointError(f"{p} has checkpoint version {payload.get('version')}, this code reads {VERSION}")
    try:
        config = HSPConfig.from_json(json.loads(payload["config"]))
    except (KeyError, TypeError, ValueError, SkillGenError) as e:
        raise CheckpointError(f"{p} has a malformed config: {e}")
    sds, opts = payload.get("state_dicts"), payload.get("optimizers", {})
    if not isinstance(sds, dict) or not isinstance(opts, dict):
        raise CheckpointError(f"{p} has no state_dicts")
    return config, sds, opts


def check_layout(config: HSPConfig, expect_task: str | None = None,
                 expect_obs: Mapping[str, tuple[int, ...]] | None = None, where: str = "checkpoint") -> None:
    """Refuse a checkpoint for another task, or whose observation layout differs from the caller's."""
    if expect_task is not None and config.task != expect_task:
        raise CheckpointError(f"{where} was trained for task {config.task!r}, not {expect_task!r}")
    if expect_task is not None:
        from ..tasks import get_task

        task = get_task(expect_task)
        known = {o.id for o in task.objects} | ({task.obstacle.id} if task.obstacle else set())
        if not set(config.object_ids) <= known:
            raise CheckpointError(f"{where} observes objects {list(config.object_ids)}, "
                                  f"task {expect_task} has {sorted(known)}")
    if expect_obs is not None:
        for k in config.obs_keys:
            got = expect_obs.get(k)
            if got is None or tuple(got) != tuple(config.obs_shapes[k]):
                raise CheckpointError(f"{where} reads observation {k!r} of shape {tuple(config.obs_shapes[k])}, "
                                      f"the environment gives {None if got is None else tuple(got)}")


def load_networks(config: HSPConfig, state_dicts: Mapping, where: str = "checkpoint") -> dict[str, torch.nn.Module]:
    nets = build_networks(config)
    if set(nets) != set(state_dicts):
        raise CheckpointError(f"{where} holds networks {sorted(state_dicts)}, its config describes {sorted(nets)}")
    for k, net in nets.items():
        try:
            net.load_state_dict(state_dicts[k], strict=True)
        except (RuntimeError, TypeError, KeyError) as e:
            raise CheckpointError(f"{where}: {k} weights do not match its config ({str(e).splitlines()[0][:200]})")
    return nets


def resolve_device(device: str) -> str:
    if device not in ("cpu", "cuda") and not device.startswith("cuda:"):
        raise ParameterError(f"device must be cpu or cuda[:N], got {device!r}")
    if device.startswith("cuda") and not torch.cuda.is_available():
        raise ParameterError(f"device {device!r} asked for but no CUDA device is available",
                             reason="DEVICE_UNAVAILABLE")
    return device


def load_hsp(path: str | os.PathLike, device: str = "cpu", expect_task: str | None = None,
             expect_obs: Mapping[str, tuple[int, ...]] | None = None) -> HybridSkillPolicy:
    """The policy of a checkpoint, ready to act. expect_obs: key -> per-step shape the caller will feed
    (e.g. {k: v.shape for k, v in policy_obs(o).items()}); a mismatch is BAD_CHECKPOINT, not a crash later."""
    config, sds, _ = read_checkpoint(path)
    check_layout(config, expect_task, expect_obs, where=str(path))
    return HybridSkillPolicy(config, load_networks(config, sds, where=str(path)), resolve_device(device))

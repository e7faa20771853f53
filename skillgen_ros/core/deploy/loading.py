"""What a deployment loads before its first rollout: the checkpoint and the task's source demos.

Every mismatch is BAD_CHECKPOINT with the reason in words: a checkpoint for another task, one
without the head the initiation mode needs (class: Class head + T, reg: Reg head + T), or
trained on a different number of source demos than are loaded now (the Class head's labels index
that list, in generation's order: core/skills/bag_demos.expand_bag_paths).
"""
from __future__ import annotations

import os
from typing import Sequence

from ..errors import CheckpointError, SkillGenError
from ..skills.bag_demos import expand_bag_paths, load_source_demos
from ..skills.segment import SourceDemo
from ..tasks import get_task
from .initiation import check_mode

DEFAULT_DEMOS_DIR = "bags"  # <dir>/<task>/ holds the source demo bags, as generation reads them


def load_demos(task: str, demos_dir: str = DEFAULT_DEMOS_DIR) -> list[SourceDemo]:
    """The task's source demos as generation loads them (datagen node, skillgen generate)."""
    paths = expand_bag_paths([os.path.join(demos_dir, task)])
    if not paths:
        raise SkillGenError(f"no source demo bags under {os.path.join(demos_dir, task)}", reason="NO_SOURCE_DEMOS")
    return load_source_demos(paths, get_task(task))


def check_policy(policy, task: str, mode: str, demos: Sequence[SourceDemo]) -> None:
    """Raise CheckpointError unless `policy` can run `task` with initiation `mode` and these demos."""
    check_mode(mode)
    c = policy.config
    if c.task != task:
        raise CheckpointError(f"checkpoint is for task {c.task!r}, not {task!r}")
    needs = {"class": ("has_class", "has_termination"), "reg": ("has_reg", "has_termination")}.get(mode, ())
    missing = [n for n in needs if not getattr(c, n, False)]
    if missing:
        raise CheckpointError(f"initiation mode {mode!r} needs {', '.join(m[4:] for m in missing)} heads, which this "
                              f"checkpoint ({c.method}) lacks")
    if mode in ("class", "tamp") and demos and int(c.num_source_demos) != len(demos):
        raise CheckpointError(f"checkpoint was trained on {c.num_source_demos} source demos, {len(demos)} are loaded")


def load_policy(checkpoint: str, task: str, mode: str, device: str = "cpu", demos_dir: str = DEFAULT_DEMOS_DIR):
    """(policy, source demos) ready for run_rollout; BAD_CHECKPOINT / UNKNOWN_TASK / NO_SOURCE_DEMOS otherwise."""
    from ..learning.checkpoint import load_hsp

    get_task(task)  # UNKNOWN_TASK before touching the file
    check_mode(mode)
    if not checkpoint or not os.path.isfile(checkpoint):
        raise CheckpointError(f"no checkpoint file at {checkpoint!r}")
    policy = load_hsp(checkpoint, device=device, expect_task=task)
    demos = load_demos(task, demos_dir) if mode in ("class", "tamp") else []
    check_policy(policy, task, mode, demos)
    return policy, demos

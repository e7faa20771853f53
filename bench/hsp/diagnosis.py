"""bench/hsp/diagnosis: the loop every HSP diagnostic shares (bc_diagnosis.py, skill_diagnosis.py).

A checkpoint's rollouts on the benchmark's held-out reset seeds (rollout_seed(seed, i), as
bench/hsp/run.py), in-process with ground-truth object poses, torch on one CPU thread; each
diagnostic says what to record of a rollout."""
from __future__ import annotations

from typing import Callable


def diagnose_rollouts(checkpoint: str, seed: int, rollouts: int,
                      make_row: Callable[..., Callable[[int], dict]]):
    """make_row(env, policy, spec) -> row(reset_seed) -> dict, called once per rollout (printed as it
    comes). Returns (policy, spec, rows); the env is closed whatever happens."""
    import torch

    from skillgen_ros.core.deploy.evaluate import make_env
    from skillgen_ros.core.deploy.seeds import rollout_seed
    from skillgen_ros.core.learning.checkpoint import load_hsp
    from skillgen_ros.core.tasks import get_task

    torch.set_num_threads(1)
    policy = load_hsp(checkpoint, device="cpu")
    spec = get_task(policy.config.task)
    env = make_env("ground_truth", seed=seed)
    rows = []
    try:
        row = make_row(env, policy, spec)
        for i in range(rollouts):
            rows.append(row(rollout_seed(seed, i)))
            print(rows[-1], flush=True)
    finally:
        env.close()
    return policy, spec, rows

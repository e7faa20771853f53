"""Evaluation rollouts in-process: N rollouts of one checkpoint on held-out reset seeds, summarized.

`skillgen train` calls `evaluate` every K epochs (robomimic's rollouts during training) and the
benchmark (bench/hsp) per checkpoint; `skillgen deploy --in-process` prints the same summary.
The env is core/generation/sim_env.SimGenerationEnv, as generation uses it; perception defaults
to ground truth because the paper's HSP-Class "assumes that object poses are known" (Sec. 4).
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Callable, Sequence

from ..dataset.report import wilson_interval
from ..tasks import get_task
from .loading import DEFAULT_DEMOS_DIR
from .rollout import DeployConfig, RolloutResult, run_rollout
from .seeds import rollout_seed


@dataclass(frozen=True)
class EvalSummary:
    task: str
    variant: str
    mode: str
    rollouts: int
    successes: int
    wilson_low: float
    wilson_high: float
    failures: dict  # reason -> count
    mean_steps: float
    inference_ms_per_step: float  # pi + T, mean over every policy step
    results: tuple[RolloutResult, ...] = field(repr=False, default=())

    @property
    def success_rate(self) -> float:
        return self.successes / self.rollouts if self.rollouts else 0.0

    def __float__(self) -> float:  # the trainer's hook reads evaluate(...) as its success rate
        return self.success_rate

    def line(self) -> str:
        return (f"{self.task} {self.variant} [{self.mode}]: {self.successes}/{self.rollouts} = "
                f"{100 * self.success_rate:.1f}% (95% Wilson {100 * self.wilson_low:.1f}-{100 * self.wilson_high:.1f})")

    def to_json(self) -> dict:
        return {"task": self.task, "variant": self.variant, "mode": self.mode, "rollouts": self.rollouts,
                "successes": self.successes, "success_rate": self.success_rate,
                "wilson_95": [self.wilson_low, self.wilson_high], "failures": dict(self.failures),
                "mean_steps": self.mean_steps, "inference_ms_per_step": self.inference_ms_per_step,
                "skill_endings": self.skill_endings(), "reset_seeds": [r.reset_seed for r in self.results]}

    def skill_endings(self) -> dict:
        """Per skill index, how its policy phase ended (termination, goal, budget, task_success, failed):
        a T that never fires shows as "budget"."""
        out: dict[str, Counter] = {}
        for r in self.results:
            for s in r.skills:
                out.setdefault(str(s.skill_index), Counter())[s.ended] += 1
        return {k: dict(sorted(v.items())) for k, v in sorted(out.items())}


def summarize(task: str, variant: str, mode: str, results: Sequence[RolloutResult]) -> EvalSummary:
    n, k = len(results), sum(r.success for r in results)
    lo, hi = wilson_interval(k, n) if n else (0.0, 0.0)
    fails = Counter(r.reason.value for r in results if not r.success)
    steps = sum(r.policy_steps for r in results)
    secs = sum(r.policy_seconds for r in results)
    return EvalSummary(task, variant, mode, n, k, lo, hi, dict(sorted(fails.items())),
                       sum(r.steps for r in results) / n if n else 0.0, 1000 * secs / steps if steps else 0.0,
                       tuple(results))


def make_env(perception: str = "ground_truth", images: bool = False, seed: int = 0):
    from ..generation.sim_env import SimEnvConfig, SimGenerationEnv

    return SimGenerationEnv(SimEnvConfig(perception=perception, images=images, video=False, seed=seed))


def default_mode(config) -> str:
    """The initiation mode a checkpoint was trained for: class, reg, bc (MimicGen baseline), else tamp."""
    if getattr(config, "method", "") == "mimicgen" or getattr(config, "all_steps", False):
        return "bc"
    if config.has_class and config.has_termination:
        return "class"
    return "reg" if config.has_reg and config.has_termination else "tamp"


def evaluate(checkpoint_path: str, task: str | None = None, variant: str | None = None, mode: str | None = None,
             rollouts: int = 50, seed: int = 0,
             device: str = "cpu", demos_dir: str = DEFAULT_DEMOS_DIR, config: DeployConfig | None = None,
             perception: str = "ground_truth", env=None, policy=None,
             on_rollout: Callable[[int, RolloutResult], None] | None = None, first_index: int = 0,
             torch_threads: int = 1) -> EvalSummary:
    """`rollouts` in-process rollouts of a checkpoint (or an already loaded `policy`) with
    initiation `mode` on the held-out reset seeds rollout_seed(seed, i), i = first_index, ...
    task, variant and mode default to the checkpoint's own (evaluate(path) is the trainer's hook)."""
    from .initiation import check_mode
    from .loading import check_policy, load_demos

    if task is not None:
        get_task(task)  # UNKNOWN_TASK before the checkpoint is read
    if mode is not None:
        check_mode(mode)
    if policy is None:
        from ..learning.checkpoint import load_hsp

        policy = load_hsp(checkpoint_path, device=device, expect_task=task)
    task = task or policy.config.task
    variant = variant or policy.config.variant
    mode = mode or default_mode(policy.config)
    loaded = policy
    demos = load_demos(task, demos_dir) if mode in ("class", "tamp") else []
    check_policy(loaded, task, mode, demos)
    cfg = config or DeployConfig(mode=mode)
    if cfg.mode != mode:
        cfg = DeployConfig(**{**cfg.__dict__, "mode": mode})
    own = env is None
    images = bool(getattr(loaded.config, "image_keys", ()))
    env = env or make_env(perception, images=images, seed=seed)
    spec = get_task(task)
    results = []
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(torch_threads)  # one core per step (on 2 loaded cores, 2 threads made a step 20x slower)
    try:
        for i in range(first_index, first_index + rollouts):
            r = run_rollout(env, loaded, spec, rollout_seed(seed, i), variant, cfg, demos)
            results.append(r)
            if on_rollout is not None:
                on_rollout(i, r)
    finally:
        torch.set_num_threads(threads)
        if own:
            env.close()
    return summarize(task, variant, mode, results)

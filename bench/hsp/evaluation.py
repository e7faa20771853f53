"""bench/hsp/evaluation: a checkpoint's evaluation rollouts split over processes (--eval-workers).

A rollout depends only on its reset seed (the env reseeds its planner per reset: sim_env.reset), so
the 50 rollouts of each method can run as index ranges side by side and be summarized together:
the summary is the one a single process would give. Three HSP methods x 50 rollouts took 25-30 min
a checkpoint in one process on Nut Assembly D0 (bench/results/hsp.json eval_seconds)."""
from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor


def _rollouts(job: tuple) -> tuple:
    """One worker's share: (mode, its RolloutResults) for rollouts first .. first + n - 1."""
    from skillgen_ros.core.deploy import evaluate

    ckpt, task, variant, mode, n, seed, device, first = job
    return mode, evaluate(ckpt, task, variant, mode, n, seed, device=device, first_index=first).results


def split(rollouts: int, workers: int) -> list[tuple[int, int]]:
    """(first index, count) ranges covering range(rollouts) in about equal parts."""
    bounds = [round(k * rollouts / workers) for k in range(workers + 1)]
    return [(lo, hi - lo) for lo, hi in zip(bounds[:-1], bounds[1:]) if hi > lo]


def evaluate_modes(ckpt: str, task: str, variant: str, modes, rollouts: int, seed: int, device: str,
                   workers: int) -> dict:
    """{mode: EvalSummary} over rollout_seed(seed, i), i < rollouts, each mode's ranges spread over
    `workers` spawned processes (one torch thread each, as evaluate sets)."""
    from skillgen_ros.core.deploy.evaluate import summarize

    jobs = [(ckpt, task, variant, m, n, seed, device, first) for m in modes for first, n in split(rollouts, workers)]
    results: dict[str, list] = {m: [] for m in modes}
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        for mode, rs in pool.map(_rollouts, jobs):  # in job order: each mode's ranges in index order
            results[mode].extend(rs)
    return {m: summarize(task, variant, m, results[m]) for m in modes}

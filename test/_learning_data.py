"""Small generated datasets and tiny HSP checkpoints for tests, made once per test session.

`generated_dataset(tmp_path_factory, ...)` runs the real in-process generator (pybullet sim,
ground-truth perception) until `successes` demos succeeded; `tiny_checkpoint(...)` runs
`skillgen train` with a small network for a few steps. Both are cached per session by their
arguments (a 3-demo Square D0 dataset takes ~10 s, a tiny checkpoint ~5 s).
"""
from __future__ import annotations

import shutil
from pathlib import Path

from conftest import REPO

_CACHE: dict = {}
TINY = ["--epochs", "1", "--steps-per-epoch", "5", "--hidden", "32", "--mlp-hidden", "32", "--no-progress"]


def generated_dataset(tmp_path_factory, task="Square", variant="D0", successes=3, seed=1, method="skillgen",
                      augment=False, images=False) -> Path:
    """Path of a fresh copy of a cached dataset (training writes its split masks into the file)."""
    key = ("data", task, variant, successes, seed, method, augment, images)
    if key not in _CACHE:
        from skillgen_ros.core.generation.session import RunRequest, run_generation
        from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv
        from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos
        from skillgen_ros.core.tasks import get_task

        spec = get_task(task)
        demos = load_source_demos(expand_bag_paths([str(REPO / "bags" / task)]), spec)
        out = tmp_path_factory.mktemp(f"gen_{task}_{variant}")
        env = SimGenerationEnv(SimEnvConfig(perception="ground_truth", images=images))
        try:
            req = RunRequest(task=task, variant=variant, method=method, attempts=successes * 5,
                             target_successes=successes, seed=seed, augment=augment, output_dir=str(out),
                             video_attempts=0)
            r = run_generation(env, demos, spec, req, write_report=False, keep_timings=False)
        finally:
            env.close()
        assert r.successes == successes, f"generation gave {r.successes}/{successes} demos"
        _CACHE[key] = Path(r.dataset_path)
    dst = tmp_path_factory.mktemp("dataset") / "demo.hdf5"
    shutil.copyfile(_CACHE[key], dst)
    return dst


def tiny_checkpoint(tmp_path_factory, dataset: Path, *extra: str) -> Path:
    """best.pt of `skillgen train` with a tiny network, a few steps (cached by dataset and options)."""
    key = ("ckpt", str(dataset), extra)
    if key not in _CACHE:
        from skillgen_ros.cli.train import main

        out = tmp_path_factory.mktemp("ckpt")
        assert main(["--dataset", str(dataset), "--output", str(out / "run"), *TINY, *extra]) == 0
        _CACHE[key] = out / "run" / "best.pt"
    return _CACHE[key]

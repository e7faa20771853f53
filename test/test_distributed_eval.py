"""Evaluation rollouts on Ray (core/distributed/evaluate.py): the summary equals a serial evaluate's."""
from __future__ import annotations

import pytest
from _learning_data import generated_dataset, tiny_checkpoint

from skillgen_ros.core.deploy import DeployConfig, evaluate


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    return tiny_checkpoint(tmp_path_factory, generated_dataset(tmp_path_factory))


def test_rollouts_on_two_workers_equal_the_serial_ones(checkpoint):
    from skillgen_ros.core.distributed.evaluate import evaluate_distributed

    cfg = DeployConfig(max_steps=120)
    serial = evaluate(str(checkpoint), "Square", "D0", rollouts=3, seed=2, config=cfg)
    ranges = []
    dist = evaluate_distributed(str(checkpoint), "Square", "D0", rollouts=3, seed=2, workers=2, config=cfg,
                                on_range=lambda i, s: ranges.append((i, s.rollouts)))
    assert sorted(ranges) == [(0, 1), (1, 1), (2, 1)], "one rollout per range, each taken once"
    assert [r.reset_seed for r in dist.results] == [r.reset_seed for r in serial.results]
    assert [(r.success, r.reason, r.steps) for r in dist.results] == \
        [(r.success, r.reason, r.steps) for r in serial.results]
    assert (dist.mode, dist.variant, dist.successes) == (serial.mode, serial.variant, serial.successes)

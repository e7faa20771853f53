"""bench/hsp/device.py: what travels to a lent GPU trains the same as the dataset it was packed from.

The device run is one shot (15 minutes of device time), so the parts that can be checked here are:
pack + unpack keep every array the trainer reads (floats rounded to float32, labels exact), the demo
split and the attributes dataset_info reads; a device training chunk keeps a weights-only
checkpoint that deployment loads; and the returned set fits the return limit.
"""
from __future__ import annotations

import dataclasses
import json
import sys
import time

import numpy as np
import pytest

from _learning_data import generated_dataset
from conftest import REPO

sys.path.insert(0, str(REPO))
from bench.hsp import device  # noqa: E402


@pytest.fixture(scope="module")
def packed(tmp_path_factory):
    from skillgen_ros.core.learning.data import split_train_valid

    src = generated_dataset(tmp_path_factory, successes=3)  # the suite's cached default dataset
    split_train_valid(str(src), 0.34, 0)  # the mask the original run wrote
    work = tmp_path_factory.mktemp("work")
    cell = work / "Square_D0" / "data_hsp_3"
    cell.mkdir(parents=True)
    (cell / "demo.hdf5").write_bytes(src.read_bytes())
    dest = tmp_path_factory.mktemp("gpu")
    assert device.main(["pack", "--cells", "Square/D0", "--networks", "hsp", "--demos", "3", "--work", str(work),
                        "--dest", str(dest)]) == 0
    meta = json.loads((dest / "Square_D0__hsp" / "meta.json").read_text())
    assert meta["source_demos"] == len(list((REPO / "bags" / "Square").glob("demo_*")))  # HSP-Class's classes
    out = device.unpack(dest / "Square_D0__hsp", tmp_path_factory.mktemp("unpacked") / "demo.hdf5")
    return cell / "demo.hdf5", out


def test_unpacked_dataset_reads_as_the_original(packed):
    from skillgen_ros.core.learning.data import dataset_info, read_demos, split_train_valid
    from skillgen_ros.core.learning.observation import LOW_DIM_KEYS

    src, out = packed
    a, b = dataset_info(str(src)), dataset_info(str(out))
    assert dataclasses.replace(a, obs_shapes={}) == dataclasses.replace(b, obs_shapes={})
    assert {k: a.obs_shapes[k] for k in LOW_DIM_KEYS} == b.obs_shapes  # only what the networks read travels
    assert split_train_valid(str(src), 0.5, 7) == split_train_valid(str(out), 0.5, 7)  # the stored mask, both
    for x, y in zip(read_demos(str(src), a.demos, LOW_DIM_KEYS), read_demos(str(out), b.demos, LOW_DIM_KEYS)):
        for k in LOW_DIM_KEYS:
            np.testing.assert_allclose(y.obs[k], x.obs[k], rtol=1e-6, atol=1e-6)
        np.testing.assert_array_equal(y.actions, x.actions.astype(np.float32))
        for k in ("mp_step", "source_demo", "augmented"):
            np.testing.assert_array_equal(getattr(y, k), getattr(x, k))
        np.testing.assert_allclose(y.initiation_target, x.initiation_target, rtol=1e-6, atol=1e-6)


def test_a_device_chunk_keeps_a_weights_only_checkpoint_that_deploys(packed, tmp_path):
    import torch

    from skillgen_ros.core.learning.checkpoint import load_hsp

    _, data = packed
    keep = tmp_path / "keep"
    assert device.main(["_one", "--dataset", str(data), "--work-dir", str(tmp_path / "w"), "--keep-dir", str(keep),
                        "--log", str(tmp_path / "log.json"), "--deadline", str(time.time()), "--chunk-steps", "4",
                        "--steps-per-epoch", "2", "--budget-steps", "8", "--hidden", "16", "--mlp-hidden", "16",
                        "--device", "cpu", "--source-demos", "10"]) == 0
    kept = sorted(keep.glob("step_*.pt"))
    assert [p.name for p in kept] == ["step_000004.pt"]  # the deadline has passed: one chunk, then stop
    payload = torch.load(kept[0], weights_only=True)
    assert payload["optimizers"] == {}
    policy = load_hsp(kept[0], expect_task="Square")
    assert policy.config.num_source_demos == 10 and policy.config.step == 4
    log = json.loads((tmp_path / "log.json").read_text())
    assert [c["step"] for c in log["chunks"]] == [4]


def test_returned_checkpoints_fit_the_limit_last_and_middle_first(tmp_path, monkeypatch):
    kept = {}
    for net, size in (("hsp", 5), ("bc", 2)):
        d = tmp_path / net
        d.mkdir()
        kept[net] = []
        for step in range(1, 6):
            p = d / f"step_{step:06d}.pt"
            p.write_bytes(b"x" * size)
            kept[net].append(p)
    monkeypatch.setattr(device, "RETURN_LIMIT", 20)
    chosen = device._choose(kept)
    assert sum(p.stat().st_size for p in chosen) <= 20
    assert [f"{p.parent.name}/{p.stem[-1]}" for p in chosen[:4]] == ["hsp/5", "bc/5", "hsp/3", "bc/3"]


def test_shuffled_bytes_round_trip():
    a = np.random.default_rng(0).normal(size=(7, 3)).astype(np.float32)
    np.testing.assert_array_equal(device._unshuffled(device._shuffled(a), "float32", [7, 3]), a)

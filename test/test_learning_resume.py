"""`skillgen train` resumes after an interruption exactly where it stopped; rollout hook; CLI errors."""
import dataclasses
import json

import pytest
import torch

from _learning_data import TINY, generated_dataset
from skillgen_ros.cli.main import main as skillgen
from skillgen_ros.core.errors import SkillGenError
from skillgen_ros.core.learning.checkpoint import read_checkpoint
from skillgen_ros.core.learning.config import NetworkConfig, TrainConfig
from skillgen_ros.core.learning.trainer import TrainRequest, train

NET = NetworkConfig(rnn_hidden=32, mlp_hidden=(32, 32))
CFG = TrainConfig(epochs=3, steps_per_epoch=5, batch_size=16, eval_every=0, threads=1)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    return generated_dataset(tmp_path_factory)


def _same_weights(a, b):
    _, sa, oa = read_checkpoint(a)
    _, sb, ob = read_checkpoint(b)
    for net in sa:
        for k in sa[net]:
            assert torch.equal(sa[net][k], sb[net][k]), (net, k)
    assert oa["policy"]["state"][0]["step"] == ob["policy"]["state"][0]["step"]


def test_stop_and_resume_equals_one_run(dataset, tmp_path):
    whole = train(TrainRequest(str(dataset), str(tmp_path / "whole"), NET, CFG, reg=True, progress=False))
    assert whole.finished and whole.steps_run == 15
    part = train(TrainRequest(str(dataset), str(tmp_path / "part"), NET, CFG, reg=True, stop_after=7, progress=False))
    assert not part.finished and part.steps_run == 7 and read_checkpoint(part.last_path)[0].step == 7
    with pytest.raises(SkillGenError) as e:  # a second fresh run would overwrite it
        train(TrainRequest(str(dataset), str(tmp_path / "part"), NET, CFG, progress=False))
    assert e.value.reason == "OUTPUT_EXISTS"
    rest = train(TrainRequest(str(dataset), str(tmp_path / "part"), NET, CFG, resume=True, progress=False))
    assert rest.finished and rest.steps_run == 8 and rest.config.step == 15 and rest.config.epoch == 3
    assert [h["epoch"] for h in rest.config.history] == [1, 2, 3]
    _same_weights(whole.last_path, rest.last_path)


def test_ctrl_c_saves_the_last_checkpoint_and_resume_finishes(dataset, tmp_path):
    calls = []

    def evaluate(path):  # the rollout hook; the second call plays the user's Ctrl-C
        calls.append(read_checkpoint(path)[0].step)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return 0.5

    cfg = TrainConfig(epochs=3, steps_per_epoch=5, batch_size=16, eval_every=1, threads=1)
    with pytest.raises(KeyboardInterrupt):
        train(TrainRequest(str(dataset), str(tmp_path / "run"), NET, cfg, progress=False), evaluate=evaluate)
    assert calls == [5, 10]
    saved = read_checkpoint(tmp_path / "run" / "last.pt")[0]
    assert saved.step == 10 and saved.best["metric"] == "success_rate"
    rates = iter([0.9])
    r = train(TrainRequest(str(dataset), str(tmp_path / "run"), NET, cfg, resume=True, progress=False),
              evaluate=lambda p: next(rates))
    assert r.finished and r.config.step == 15
    best = read_checkpoint(r.best_path)[0]
    assert best.best == {"metric": "success_rate", "value": 0.9, "epoch": 3, "step": 15}


def test_best_checkpoint_is_the_best_rollout_epoch(dataset, tmp_path):
    rates = iter([0.2, 0.6, 0.4])
    r = train(TrainRequest(str(dataset), str(tmp_path / "run"), NET,
                           TrainConfig(epochs=3, steps_per_epoch=2, batch_size=8, eval_every=1, threads=1),
                           progress=False), evaluate=lambda p: next(rates))
    best = read_checkpoint(r.best_path)[0]
    assert (best.best["epoch"], best.best["value"], best.step) == (2, 0.6, 4)
    assert [h["success_rate"] for h in r.config.history] == [0.2, 0.6, 0.4]
    assert r.config.best["epoch"] == 2  # last.pt remembers which epoch was best


def test_cli_trains_stops_resumes_and_refuses_bad_input(dataset, tmp_path, capsys):
    out = str(tmp_path / "cli")
    args = ["train", "--dataset", str(dataset), "--output", out, "--threads", "1", *TINY]
    assert skillgen([*args, "--epochs", "2", "--stop-after", "3"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert (first["step"], first["finished"]) == (3, False)
    assert skillgen([*args, "--epochs", "2", "--resume"]) == 0
    done = json.loads(capsys.readouterr().out)
    assert (done["step"], done["epoch"], done["finished"]) == (10, 2, True)
    assert skillgen([*args, "--epochs", "2"]) == 2
    assert "OUTPUT_EXISTS" in capsys.readouterr().err
    assert skillgen(["train", "--dataset", str(tmp_path / "none.hdf5"), "--output", str(tmp_path / "x"), *TINY]) == 2
    assert "BAD_DATASET" in capsys.readouterr().err
    assert skillgen(["train", "--dataset", str(dataset), "--output", str(tmp_path / "y"), "--hidden", "0"]) == 2
    assert "INVALID_PARAMETER" in capsys.readouterr().err
    assert skillgen(["train", "--dataset", str(dataset), "--output", str(tmp_path / "z"), "--images", *TINY]) == 2
    assert "MISSING_IMAGES" in capsys.readouterr().err
    if not torch.cuda.is_available():
        assert skillgen(["train", "--dataset", str(dataset), "--output", str(tmp_path / "c"), "--device", "cuda",
                         *TINY]) == 2
        assert "DEVICE_UNAVAILABLE" in capsys.readouterr().err


def test_the_deployment_evaluate_hook_ranks_checkpoints(dataset, tmp_path):
    """Without an injected hook the trainer calls skillgen_ros.core.deploy.evaluate (real in-process
    rollouts in the sim; success is not expected from a 2-step policy)."""
    pytest.importorskip("skillgen_ros.core.deploy")
    cfg = TrainConfig(epochs=1, steps_per_epoch=2, batch_size=8, eval_every=1, eval_rollouts=1, threads=1)
    r = train(TrainRequest(str(dataset), str(tmp_path / "run"), NET, cfg, progress=False))
    rec = r.config.history[-1]
    assert rec["success_rate"] in (0.0, 1.0) and len(rec["success_wilson95"]) == 2
    assert read_checkpoint(r.best_path)[0].best["metric"] == "success_rate"


def test_class_head_covers_every_source_demo(tmp_path):
    from conftest import REPO
    from skillgen_ros.core.learning.trainer import count_source_demos

    assert count_source_demos(str(REPO / "bags"), "Square", 4) == 10  # bags/Square holds demo_00..demo_09
    assert count_source_demos(str(tmp_path), "Square", 4) == 4  # no folder: the labels seen
    with pytest.raises(SkillGenError) as e:
        count_source_demos(str(REPO / "bags"), "Square", 11)
    assert e.value.reason == "SOURCE_DEMOS_MISMATCH"


def test_a_request_can_name_the_class_count(tmp_path):
    """bench/hsp/device.py trains where bags/ cannot be read: the count travels in the request."""
    from types import SimpleNamespace

    from skillgen_ros.core.learning.trainer import TrainRequest, _classes

    info = SimpleNamespace(task="Square", num_source_demos=4)
    req = TrainRequest(dataset="unused", output_dir="unused", demos_dir=str(tmp_path))
    assert _classes(req, info) == 4  # no count, no folder: the labels seen
    assert _classes(dataclasses.replace(req, num_source_demos=12), info) == 12
    with pytest.raises(SkillGenError) as e:
        _classes(dataclasses.replace(req, num_source_demos=3), info)  # fewer classes than labels
    assert e.value.reason == "SOURCE_DEMOS_MISMATCH"


def test_a_real_sigint_stops_at_the_next_step_boundary(dataset, tmp_path):
    import os
    import signal

    def evaluate(path):  # the user presses Ctrl-C while epoch 1's rollouts run
        os.kill(os.getpid(), signal.SIGINT)
        return 0.0

    cfg = TrainConfig(epochs=3, steps_per_epoch=4, batch_size=8, eval_every=1, threads=1)
    # a handler of our own: pytest's process may hold any (an earlier test's rclpy or Ray may have
    # left SIG_IGN), and train() must restore whatever it found
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            train(TrainRequest(str(dataset), str(tmp_path / "run"), NET, cfg, progress=False), evaluate=evaluate)
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the handler was restored
    finally:
        signal.signal(signal.SIGINT, before)
    saved = read_checkpoint(tmp_path / "run" / "last.pt")[0]
    assert (saved.step, saved.epoch, len(saved.history)) == (4, 1, 1)  # the epoch finished, no step after it


def test_validation_demos_are_split_off_and_rank_the_best(tmp_path_factory, tmp_path):
    import h5py

    data = generated_dataset(tmp_path_factory)  # a fresh copy with no split yet
    cfg = TrainConfig(epochs=2, steps_per_epoch=2, batch_size=8, valid_ratio=0.5, eval_every=0, threads=1)
    r = train(TrainRequest(str(data), str(tmp_path / "run"), NET, cfg, progress=False))
    assert len(r.config.valid_demos) == 1 and len(r.config.train_demos) == 2  # int(0.5 * 3)
    with h5py.File(data, "r") as f:
        assert sorted(n.decode() for n in f["mask/valid"][()]) == list(r.config.valid_demos)
        assert sorted(n.decode() for n in f["mask/train"][()]) == list(r.config.train_demos)
    hist = r.config.history
    assert all("valid_policy" in h and "valid_termination_acc" in h for h in hist)
    assert r.config.best["metric"] == "valid_policy"
    assert r.config.best["value"] == min(h["valid_policy"] for h in hist)
    # the stored split wins over a different ratio later
    r2 = train(TrainRequest(str(data), str(tmp_path / "run2"), NET, TrainConfig(epochs=1, steps_per_epoch=1,
                                                                                 batch_size=8, eval_every=0)))
    assert r2.config.valid_demos == r.config.valid_demos


def test_a_read_only_dataset_trains_with_an_unstored_split(tmp_path_factory, tmp_path, monkeypatch, caplog):
    import h5py

    from skillgen_ros.core.learning import data as data_mod

    data = generated_dataset(tmp_path_factory)
    real = h5py.File

    def read_only(path, mode="r", **kw):  # what a file on a read-only mount does (root ignores chmod)
        if mode != "r":
            raise OSError(30, "Read-only file system")
        return real(path, mode, **kw)

    monkeypatch.setattr(data_mod.h5py, "File", read_only)
    cfg = TrainConfig(epochs=1, steps_per_epoch=1, batch_size=8, valid_ratio=0.5, eval_every=0, threads=1)
    r = train(TrainRequest(str(data), str(tmp_path / "run"), NET, cfg, progress=False))
    assert r.finished and len(r.config.valid_demos) == 1
    assert "could not store the split" in caplog.text
    with real(data, "r") as f:
        assert "train" not in f["mask"]

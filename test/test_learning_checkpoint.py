"""Checkpoints: weights_only round trip, and every way a file can be a bad checkpoint."""
import io
import json
import pickle
import zipfile

import h5py
import numpy as np
import pytest
import torch

from _learning_data import generated_dataset, tiny_checkpoint
from skillgen_ros.core.errors import CheckpointError, InvalidInputError
from skillgen_ros.core.learning import load_hsp
from skillgen_ros.core.learning.checkpoint import FORMAT, read_checkpoint, save_checkpoint
from skillgen_ros.core.learning.observation import add_derived


@pytest.fixture(scope="module")
def ckpt(tmp_path_factory):
    return tiny_checkpoint(tmp_path_factory, generated_dataset(tmp_path_factory))


def _first_obs(cfg, t=0):
    with h5py.File(cfg.dataset_path, "r") as f:
        g = f["data"][cfg.train_demos[0]]["obs"]
        return add_derived({k: g[k][t] for k in g})  # what policy_obs gives the policy


def test_round_trip_gives_the_same_networks_and_config(ckpt, tmp_path):
    p = load_hsp(ckpt, expect_task="Square")
    cfg = p.config
    assert (cfg.task, cfg.method, cfg.skills) == ("Square", "skillgen", ("grasp_nut", "place_on_peg"))
    assert cfg.has_termination and cfg.has_class and not cfg.has_reg and cfg.num_source_demos >= 1
    assert cfg.step == 5 and cfg.epoch == 1 and cfg.network.rnn_hidden == 32 and len(cfg.dataset_sha256) == 64
    # weights_only load of the raw file works and holds only tensors and plain data
    raw = torch.load(ckpt, weights_only=True)
    assert raw["format"] == FORMAT and set(raw["state_dicts"]) == {"policy", "termination"}
    assert set(raw["optimizers"]) == {"policy", "termination"}
    save_checkpoint(tmp_path / "again.pt", cfg, p.nets)
    q = load_hsp(tmp_path / "again.pt")
    assert q.config == cfg
    for name in p.nets:
        for (k, a), (_, b) in zip(p.nets[name].state_dict().items(), q.nets[name].state_dict().items()):
            assert torch.equal(a, b), (name, k)
    o = _first_obs(cfg)
    p.start_skill(0)
    q.start_skill(0)
    acts = [(p.act(o), q.act(o)) for _ in range(12)]
    for a, b in acts:
        np.testing.assert_array_equal(a, b)
    assert acts[0][0].shape == (7,) and np.all(np.abs(acts[0][0]) <= 1)
    assert p.initiation_source_demo(o) == q.initiation_source_demo(o)
    assert cfg.train.reg_target == "nominal"
    # a checkpoint written before train.reg_target existed trained I on the stored labels
    from skillgen_ros.core.learning.config import HSPConfig

    old = cfg.to_json()
    del old["train"]["reg_target"]
    assert HSPConfig.from_json(old).train.reg_target == "initiation_target"
    # and T on the paper's labels
    del old["train"]["termination_labels"]
    assert cfg.train.termination_labels == HSPConfig.from_json(old).train.termination_labels == "paper"


def test_missing_heads_and_bad_observations_are_clear(ckpt):
    p = load_hsp(ckpt)
    o = _first_obs(p.config)
    with pytest.raises(CheckpointError, match="HSP-Reg"):
        p.initiation_pose(o)
    with pytest.raises(InvalidInputError, match="lacks 'object'"):
        p.act({k: v for k, v in o.items() if k != "object"})
    with pytest.raises(InvalidInputError, match="skill index"):
        p.start_skill(7)


class _Evil:
    def __reduce__(self):
        import os

        return (os.system, ("echo pwned",))


def _bad_cases(ckpt, tmp_path):
    data = ckpt.read_bytes()
    (tmp_path / "truncated.pt").write_bytes(data[: len(data) // 2])
    (tmp_path / "random.pt").write_bytes(np.random.default_rng(0).bytes(4096))
    (tmp_path / "evil.pt").write_bytes(pickle.dumps({"format": FORMAT, "x": _Evil()}))
    torch.save({"format": FORMAT, "x": _Evil()}, tmp_path / "evil_torch.pt")
    torch.save({"some": torch.zeros(3)}, tmp_path / "other.pt")
    (tmp_path / "text.pt").write_text("not a checkpoint")
    return {"missing": (tmp_path / "nope.pt", "does not exist"), "truncated": (tmp_path / "truncated.pt", "readable"),
            "random bytes": (tmp_path / "random.pt", "readable"),
            "pickle with code": (tmp_path / "evil.pt", "readable"),
            "torch pickle with code": (tmp_path / "evil_torch.pt", "readable"),
            "another format": (tmp_path / "other.pt", "not a skillgen_ros HSP checkpoint"),
            "text": (tmp_path / "text.pt", "readable"), "a directory": (tmp_path, "does not exist")}


def test_every_bad_file_is_bad_checkpoint(ckpt, tmp_path, capfd):
    for name, (path, why) in _bad_cases(ckpt, tmp_path).items():
        with pytest.raises(CheckpointError) as e:
            load_hsp(path)
        assert e.value.reason == "BAD_CHECKPOINT" and why in str(e.value), (name, str(e.value))
    assert "pwned" not in capfd.readouterr().out  # the code in the pickle never ran


def _rewrite(ckpt, path, edit_config=None, edit_state=None):
    raw = torch.load(ckpt, weights_only=True)
    if edit_config:
        c = json.loads(raw["config"])
        edit_config(c)
        raw["config"] = json.dumps(c)
    if edit_state:
        edit_state(raw)
    torch.save(raw, path)
    return path


def test_other_task_other_layout_and_mismatched_weights(ckpt, tmp_path):
    with pytest.raises(CheckpointError, match="trained for task 'Square', not 'Threading'"):
        load_hsp(ckpt, expect_task="Threading")
    o = _first_obs(load_hsp(ckpt).config)
    shapes = {k: v.shape for k, v in o.items()}
    load_hsp(ckpt, expect_task="Square", expect_obs=shapes)  # the right layout loads
    with pytest.raises(CheckpointError, match="'object' of shape \\(14,\\)"):
        load_hsp(ckpt, expect_obs={**shapes, "object": (21,)})  # e.g. the clutter variant's 3 objects
    with pytest.raises(CheckpointError, match="robot0_gripper_qpos"):
        load_hsp(ckpt, expect_obs={k: v for k, v in shapes.items() if k != "robot0_gripper_qpos"})

    def other_task(c):
        c["task"], c["object_ids"] = "Threading", ["needle", "tripod"]

    with pytest.raises(CheckpointError, match="not 'Square'"):
        load_hsp(_rewrite(ckpt, tmp_path / "t.pt", other_task), expect_task="Square")

    def other_layout(c):
        c["obs_shapes"]["object"] = [21]

    with pytest.raises(CheckpointError, match="weights do not match"):
        load_hsp(_rewrite(ckpt, tmp_path / "l.pt", other_layout))
    with pytest.raises(CheckpointError, match="malformed config"):
        load_hsp(_rewrite(ckpt, tmp_path / "m.pt", lambda c: c.pop("task")))
    with pytest.raises(CheckpointError, match="holds networks"):
        load_hsp(_rewrite(ckpt, tmp_path / "n.pt", edit_state=lambda r: r["state_dicts"].pop("termination")))
    with pytest.raises(CheckpointError, match="version"):
        load_hsp(_rewrite(ckpt, tmp_path / "v.pt", edit_state=lambda r: r.update(version=99)))


def test_an_interrupted_save_leaves_the_old_checkpoint(ckpt, tmp_path, monkeypatch):
    p = load_hsp(ckpt)
    target = tmp_path / "last.pt"
    save_checkpoint(target, p.config, p.nets)
    before = target.read_bytes()

    def boom(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(torch, "save", boom)
    with pytest.raises(KeyboardInterrupt):
        save_checkpoint(target, p.config, p.nets)
    assert target.read_bytes() == before
    read_checkpoint(target)
    assert zipfile.is_zipfile(io.BytesIO(before))

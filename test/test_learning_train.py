"""Training: π, T and the HSP-Class head overfit a 3-demo dataset; HSP-Reg fits its targets."""
from pathlib import Path

import h5py
import numpy as np
import pytest
import torch

from _learning_data import generated_dataset
from skillgen_ros.core.learning import load_hsp
from skillgen_ros.core.learning.config import NetworkConfig, TrainConfig
from skillgen_ros.core.learning.data import initiation_indices
from skillgen_ros.core.learning.hsp import HybridSkillPolicy
from skillgen_ros.core.learning.networks import build_networks
from skillgen_ros.core.learning.observation import add_derived
from skillgen_ros.core.learning.termination import segments, termination_labels
from skillgen_ros.core.learning.trainer import TrainRequest, train

# Small networks and lr 3e-3 (robomimic: 400 / 1024 and 1e-4) so a 3-demo overfit takes ~1500 steps.
SMALL = NetworkConfig(rnn_hidden=64, mlp_hidden=(64, 64))
OVERFIT = TrainConfig(lr=3e-3, epochs=30, steps_per_epoch=50, eval_every=0, threads=1)


@pytest.fixture(scope="module")
def overfit(tmp_path_factory):
    data = generated_dataset(tmp_path_factory)
    out = tmp_path_factory.mktemp("overfit") / "run"
    r = train(TrainRequest(str(data), str(out), SMALL, OVERFIT, reg=True, progress=False))
    return r, load_hsp(r.last_path, expect_task="Square")


def _demos(cfg):
    with h5py.File(cfg.dataset_path, "r") as f:
        for n in cfg.train_demos:
            g = f["data"][n]
            yield (add_derived({k: g["obs"][k][()] for k in g["obs"]}), g["actions"][()], g["labels/mp_step"][()],
                   g["labels/source_demo"][()], g["labels/initiation_target"][()])


def _step(obs, t):
    return {k: v[t] for k, v in obs.items()}


def _action_mse(p: HybridSkillPolicy) -> float:
    """Deployed-path error: act() through every skill segment of the training demos, from a fresh state."""
    err = []
    for obs, actions, mp, *_ in _demos(p.config):
        for a, b in segments(mp == 0):
            p.start_skill(0)
            err += [np.mean((p.act(_step(obs, t)) - actions[t]) ** 2) for t in range(a, b)]
    return float(np.mean(err))


def test_policy_action_error_drops_tenfold(overfit):
    r, p = overfit
    cfg = p.config
    assert r.finished and cfg.step == 1500 and len(cfg.history) == 30
    assert not cfg.all_steps and cfg.train_demos and not cfg.valid_demos  # int(0.1 * 3) = 0 validation demos
    torch.manual_seed(0)
    untrained = HybridSkillPolicy(cfg, build_networks(cfg))
    before, after = _action_mse(untrained), _action_mse(p)
    # The GMM NLL goes negative as the scales shrink, so "drops 10x" is measured on the deployed
    # action (mean of the top mode) against the dataset's action.
    assert after * 10 <= before, (before, after)
    assert cfg.history[-1]["policy"] < cfg.history[0]["policy"] - 10


def test_termination_reaches_95_percent_and_class_100(overfit):
    _, p = overfit
    hits, cls = [], []
    for obs, _, mp, src, _ in _demos(p.config):
        labels = termination_labels(mp)
        hits += [(p.termination_probability(_step(obs, t)) > 0.5) == bool(labels[t]) for t in range(len(mp))]
        cls += [p.initiation_source_demo(_step(obs, t)) == src[a] for t, a in initiation_indices(mp, 5)]
    assert np.mean(hits) >= 0.95, np.mean(hits)
    assert len(cls) >= 6 and all(cls)


def _angle(q1, q2) -> float:
    return 2 * np.arccos(min(1.0, abs(float(q1 @ q2))))


def test_reg_predicts_the_initiation_targets(overfit):
    """Most initiation samples fit closely. Not all: the first skill's samples (home pose, only the
    nut differs) can still share one GMM mode after 1500 steps, so this checks the median, against
    what predicting the targets' mean orientation gives (42 deg): a tenth of it. (An absolute 2 deg
    was one machine's numbers: 1.9 deg there, 2.03 deg on an Intel Xeon rocketlake, same seeds.)"""
    _, p = overfit
    pos, ang, targets = [], [], []
    for obs, _, mp, _, target in _demos(p.config):
        for t, a in initiation_indices(mp, 5):
            pose = p.initiation_pose(_step(obs, t))
            assert pose.shape == (7,) and abs(np.linalg.norm(pose[3:]) - 1) < 1e-9
            pos.append(np.linalg.norm(pose[:3] - target[a, :3]))
            ang.append(_angle(pose[3:], target[a, 3:]))
            targets.append(target[a, 3:])
    mean = np.mean([q if q @ targets[0] >= 0 else -q for q in targets], axis=0)  # q and -q are one rotation
    constant = np.median([_angle(q, mean / np.linalg.norm(mean)) for q in targets])
    assert np.median(pos) < 0.005, pos
    assert np.median(ang) < 0.1 * constant, (np.degrees(ang), np.degrees(constant))


def test_two_policies_from_one_checkpoint_roll_out_identically(overfit):
    r, p = overfit
    q = load_hsp(r.last_path)
    obs, *_ = next(_demos(p.config))
    p.start_skill(1)
    q.start_skill(1)
    for t in range(25):
        np.testing.assert_array_equal(p.act(_step(obs, t)), q.act(_step(obs, t)))
        assert p.terminated(_step(obs, t)) == q.terminated(_step(obs, t))


def test_loss_curves_and_checkpoints_are_written(overfit):
    r, _ = overfit
    run = Path(r.last_path).parent
    assert (run / "loss_curves.png").stat().st_size > 1000
    best = load_hsp(r.best_path)
    # no validation demos and no rollouts: the best is the epoch with the lowest training π loss
    hist = r.config.history
    assert best.config.best["metric"] == "policy"
    assert best.config.best["value"] == min(h["policy"] for h in hist[: best.config.best["epoch"]])
    assert all(k in hist[-1] for k in ("seconds_policy", "seconds_termination", "seconds_initiation"))
    with h5py.File(r.config.dataset_path, "r") as f:  # robomimic's filter keys
        assert [n.decode() for n in f["mask/train"][()]] == list(r.config.train_demos)
        assert len(f["mask/valid"][()]) == 0

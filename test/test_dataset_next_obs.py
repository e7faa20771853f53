"""`skillgen dataset export --format robomimic-next-obs` (issue 24): next_obs/ for robomimic's offline RL.

The layout test always runs; the loader test uses robomimic's own SequenceDataset(load_next_obs=True)
and skips only where robomimic is not installed (scripts/bootstrap.sh installs robomimic 0.3.0 from
requirements-extras.txt, so it runs in scripts/test.sh)."""
import hashlib
import inspect

import h5py
import numpy as np
import pytest
from test_dataset_hdf5 import demos, generate  # noqa: F401  (the module's fixture and fake generator)

from skillgen_ros.cli import dataset as dataset_cli
from skillgen_ros.core.dataset.hdf5 import DatasetError, validate_dataset
from skillgen_ros.core.dataset.next_obs import add_next_obs, next_observations


@pytest.fixture
def exported(tmp_path, demos):  # noqa: F811
    sink = generate(tmp_path / "run", demos, n=3)
    src = sink.dataset_path
    before = hashlib.sha256(open(src, "rb").read()).hexdigest()
    dst = str(tmp_path / "next_obs.hdf5")
    assert dataset_cli.main(["export", src, "--format", "robomimic-next-obs", "-o", dst]) == 0
    assert hashlib.sha256(open(src, "rb").read()).hexdigest() == before, "the input must not change"
    return src, dst


def test_next_obs_is_obs_one_step_on(exported):
    src, dst = exported
    assert validate_dataset(dst).num_demos == validate_dataset(src).num_demos > 0
    with h5py.File(src, "r") as a, h5py.File(dst, "r") as b:
        for name in a["data"]:
            obs, nxt = a["data"][name]["obs"], b["data"][name]["next_obs"]
            assert set(nxt) == set(obs)
            for k in obs:
                o, n = obs[k][()], nxt[k][()]
                assert np.array_equal(n[:-1], o[1:]) and np.array_equal(n[-1], o[-1]), k
            assert b["data"][name]["dones"][-1] == 1  # the repeated last row is a terminal transition
            assert nxt["front_image"].compression == obs["front_image"].compression == "gzip"
            assert np.array_equal(b["data"][name]["actions"][()], a["data"][name]["actions"][()])


def test_export_refuses_its_input_and_existing_files_and_the_validator_checks_next_obs(exported, tmp_path):
    src, dst = exported
    for out in (src, dst):
        with pytest.raises(DatasetError) as e:
            add_next_obs(src, out)
        assert e.value.reason == "OUTPUT_EXISTS"
    with h5py.File(dst, "r+") as f:
        k = next(iter(f["data"]))
        del f["data"][k]["next_obs"]["robot0_eef_pos"]
    with pytest.raises(DatasetError) as e:
        validate_dataset(dst)
    assert "next_obs" in str(e.value)
    assert next_observations(np.zeros((0, 3))).shape == (0, 3)


def test_robomimic_sequence_dataset_loads_next_obs(exported):
    pytest.importorskip("robomimic", reason="robomimic is not installed (bash scripts/bootstrap.sh installs "
                                            "requirements-extras.txt); the layout test above checks next_obs without it")
    import robomimic.utils.obs_utils as ObsUtils
    from robomimic.utils.dataset import SequenceDataset

    _, dst = exported
    keys = ["robot0_eef_pos", "robot0_eef_quat", "robot0_gripper_qpos", "object"]
    ObsUtils.initialize_obs_utils_with_obs_specs({"obs": {"low_dim": keys, "rgb": []}})
    extra = {}
    if "action_keys" in inspect.signature(SequenceDataset.__init__).parameters:  # robomimic >= 0.4 (GitHub)
        extra = {"action_keys": ("actions",), "action_config": {"actions": {"normalization": None}}}
    ds = SequenceDataset(hdf5_path=dst, obs_keys=keys, dataset_keys=("actions", "rewards", "dones"),
                         load_next_obs=True, frame_stack=1, seq_length=1, pad_frame_stack=True, pad_seq_length=True,
                         get_pad_mask=False, goal_mode=None, hdf5_cache_mode="low_dim", hdf5_use_swmr=True,
                         hdf5_normalize_obs=False, filter_by_attribute=None, **extra)
    with h5py.File(dst, "r") as f:
        demo = f["data/demo_0"]
        T = int(demo.attrs["num_samples"])
        obs = {k: demo["obs"][k][()] for k in keys}
    assert len(ds) == validate_dataset(dst).total
    for t in range(T):  # demo_0's transitions come first
        item = ds[t]
        for k in keys:
            want = obs[k][min(t + 1, T - 1)]
            assert np.allclose(item["next_obs"][k][0], want), (t, k)
            assert np.allclose(item["obs"][k][0], obs[k][t]), (t, k)

"""Image observations (ResNet-18 + spatial softmax, pixel shift), the MimicGen BC-RNN baseline, and
which heads a dataset gets."""
import json
import shutil

import h5py
import numpy as np
import pytest
import torch

from _learning_data import TINY, generated_dataset, tiny_checkpoint
from skillgen_ros.core.errors import CheckpointError, InvalidInputError
from skillgen_ros.core.learning import load_hsp
from skillgen_ros.core.learning.networks import build_networks
from skillgen_ros.core.learning.observation import add_derived
from skillgen_ros.core.learning.resnet import ImageEncoder, ResNet18Conv, pixel_shift


def test_resnet18_trunk_has_torchvisions_size_and_shapes():
    trunk = ResNet18Conv()
    # torchvision resnet18: 11,689,512 parameters, of which fc holds 512*1000+1000
    assert sum(p.numel() for p in trunk.parameters()) == 11_689_512 - 513_000
    assert trunk(torch.zeros(2, 3, 84, 84)).shape == (2, 512, 3, 3)
    enc = ImageEncoder()
    assert enc(torch.zeros(2, 84, 84, 3, dtype=torch.uint8)).shape == (2, 64)


def test_pixel_shift_moves_each_image_by_at_most_ten_percent():
    torch.manual_seed(0)
    x = torch.arange(2 * 3 * 84 * 84, dtype=torch.float32).reshape(2, 3, 84, 84)
    y = pixel_shift(x, 0.1)
    padded = torch.nn.functional.pad(x, (8, 8, 8, 8), mode="replicate")
    for n in range(2):
        offsets = [(dy, dx) for dy in range(17) for dx in range(17)
                   if torch.equal(y[n], padded[n, :, dy:dy + 84, dx:dx + 84])]
        assert len(offsets) == 1
    assert not torch.equal(pixel_shift(x, 0.1), pixel_shift(x, 0.1))  # random per pass
    assert torch.equal(pixel_shift(x, 0.0), x)
    enc = ImageEncoder().eval()
    img = torch.randint(0, 255, (1, 84, 84, 3), dtype=torch.uint8)
    assert torch.equal(enc(img), enc(img))  # no shift at deployment


@pytest.fixture(scope="module")
def image_data(tmp_path_factory):
    return generated_dataset(tmp_path_factory, successes=1, images=True)


def test_a_tiny_image_run_trains_the_resnet_and_acts(image_data, tmp_path_factory):
    ckpt = tiny_checkpoint(tmp_path_factory, image_data, "--images", "--batch-size", "2", "--steps-per-epoch", "2")
    p = load_hsp(ckpt, expect_task="Square")
    cfg = p.config
    assert cfg.image_keys == ("front_image", "wrist_image") and cfg.obs_shapes["wrist_image"] == (84, 84, 3)
    torch.manual_seed(cfg.train.seed)
    init = build_networks(cfg)
    for name in ("policy", "termination"):
        before = init[name].encoder.images["front_image"].trunk.stem[0].weight
        after = p.nets[name].encoder.images["front_image"].trunk.stem[0].weight.cpu()
        assert not torch.equal(before, after), f"{name}'s ResNet got no gradient"
    with h5py.File(cfg.dataset_path, "r") as f:
        g = f["data/demo_0/obs"]
        o = add_derived({k: g[k][3] for k in g})
    p.start_skill(0)
    a = p.act(o)
    p.start_skill(0)
    np.testing.assert_array_equal(a, p.act(o))
    assert isinstance(p.terminated(o), bool)
    o_low = {k: v for k, v in o.items() if not k.endswith("_image")}
    with pytest.raises(InvalidInputError, match="front_image"):
        p.act(o_low)


def test_mimicgen_data_trains_the_bc_rnn_baseline_on_every_step(tmp_path_factory):
    data = generated_dataset(tmp_path_factory, method="mimicgen", successes=2)
    p = load_hsp(tiny_checkpoint(tmp_path_factory, data))
    cfg = p.config
    assert (cfg.method, cfg.all_steps, cfg.has_termination, cfg.has_class, cfg.has_reg) == (
        "mimicgen", True, False, False, False)
    with h5py.File(data, "r") as f:
        o = add_derived({k: v[0] for k, v in f["data/demo_0/obs"].items()})
    p.start_skill(0)
    assert p.act(o).shape == (7,)
    with pytest.raises(CheckpointError, match="no termination classifier"):
        p.terminated(o)
    with pytest.raises(CheckpointError, match="HSP-Class"):
        p.initiation_source_demo(o)


def test_an_augmented_dataset_gets_hsp_reg_by_default(tmp_path_factory, tmp_path):
    src = generated_dataset(tmp_path_factory)
    aug = tmp_path / "aug.hdf5"
    shutil.copyfile(src, aug)
    with h5py.File(aug, "a") as f:  # the flag HSP-Reg keys on (real IA data: see bench/hsp)
        env = json.loads(f["data"].attrs["env_args"])
        env["generation"]["augment"] = True
        f["data"].attrs["env_args"] = json.dumps(env)
    p = load_hsp(tiny_checkpoint(tmp_path_factory, aug))
    assert p.config.has_reg and p.config.initiation_norm is not None
    with h5py.File(aug, "r") as f:
        o = add_derived({k: v[0] for k, v in f["data/demo_0/obs"].items()})
    pose = p.initiation_pose(o)
    assert pose.shape == (7,) and abs(np.linalg.norm(pose[3:]) - 1) < 1e-9
    assert not load_hsp(tiny_checkpoint(tmp_path_factory, aug, "--no-reg")).config.has_reg

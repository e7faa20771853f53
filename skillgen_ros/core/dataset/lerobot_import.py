"""Import LeRobot's dataset classes on this project's torch build (the optional `[lerobot]` extra).

lerobot.datasets imports torchvision at module level (transforms, the old video backend). PyPI's
torchvision wheels are CUDA builds: on the CPU torch we pin (requirements.txt), their C++ ops
(`torchvision/_C.so`) cannot load (it links libtorch_cuda). torchvision handles that for every op's
fake-tensor registration except two, `torchvision::nms` and `torchvision::qnms`
(torchvision/_meta_registrations.py registers them without its `_has_ops()` guard), so `import
torchvision` raises "operator torchvision::nms does not exist". We declare those two op schemas
(no kernels: calling nms raises, as it would without _C) and import again; nothing of lerobot's
dataset path calls them. Where _C loads (a CUDA torch), the first import works and nothing is
declared. Videos decode with torchcodec (CPU wheel, system FFmpeg), not torchvision.
"""
from __future__ import annotations

import importlib
import sys

from .hdf5 import DatasetError

INSTALL_HINT = "install the extra: bash scripts/bootstrap.sh (requirements-extras.txt), or pip install .[lerobot]"
# The two ops torchvision registers unguarded (torchvision 0.28 _meta_registrations.py), with its schemas.
_UNGUARDED_OPS = ("nms(Tensor dets, Tensor scores, float iou_threshold) -> Tensor",
                  "qnms(Tensor dets, Tensor scores, float iou_threshold) -> Tensor")
_schemas = None  # the torch.library.Library holding them; it must stay alive for the definitions to stay


def _import_torchvision() -> None:
    global _schemas
    try:
        importlib.import_module("torchvision")
        return
    except RuntimeError as e:
        if "torchvision::nms does not exist" not in str(e):
            raise
    import torch

    for name in [m for m in sys.modules if m == "torchvision" or m.startswith("torchvision.")]:
        del sys.modules[name]  # the half-imported package; its guarded registrations did nothing
    _schemas = torch.library.Library("torchvision", "FRAGMENT")
    for schema in _UNGUARDED_OPS:
        _schemas.define(schema)
    importlib.import_module("torchvision")


def lerobot_dataset_class():
    """lerobot.datasets.lerobot_dataset.LeRobotDataset, or DatasetError(LEROBOT_NOT_INSTALLED) saying why not."""
    try:
        importlib.import_module("lerobot")
    except ImportError as e:
        raise DatasetError(f"LeRobot is not installed ({e}); {INSTALL_HINT}", reason="LEROBOT_NOT_INSTALLED") from e
    try:
        _import_torchvision()
        from lerobot.datasets.lerobot_dataset import LeRobotDataset
    except ImportError as e:
        raise DatasetError(f"LeRobot is installed but cannot import its dataset module ({e}); {INSTALL_HINT}",
                           reason="LEROBOT_NOT_INSTALLED") from e
    return LeRobotDataset


def codebase_version() -> str:
    """The LeRobotDataset format version the installed lerobot writes (v3.0 for lerobot 0.4)."""
    lerobot_dataset_class()
    from lerobot.datasets.lerobot_dataset import CODEBASE_VERSION

    return CODEBASE_VERSION

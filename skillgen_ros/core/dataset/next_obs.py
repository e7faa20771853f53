"""robomimic's offline-RL layout: `next_obs/<key>` beside `obs/<key>` in every demo.

robomimic's BCQ, CQL and IQL read transitions (s, a, r, s', done): their configs load
`next_obs` (SequenceDataset(load_next_obs=True)), which our files, written for behaviour cloning,
do not hold. `add_next_obs` writes a copy that does: next_obs[t] = obs[t + 1]. An attempt ends at
its last command, so there is no observation after the last step; next_obs[T - 1] repeats
obs[T - 1], and dones[T - 1] = 1 (every demo's last step, docs/dataset.md) keeps that transition
out of bootstrapped targets, as done-masking does for any terminal step. Images keep their
compression and chunking. The input is never modified.
"""
from __future__ import annotations

import os
import shutil

import h5py
import numpy as np

from .hdf5 import DatasetError, DatasetSummary, validate_dataset


def next_observations(obs: np.ndarray) -> np.ndarray:
    """obs shifted one step forward, the last row repeated (see the module docstring)."""
    obs = np.asarray(obs)
    if len(obs) == 0:
        return obs.copy()
    return np.concatenate([obs[1:], obs[-1:]], axis=0)


def add_next_obs(src: str, dst: str, overwrite: bool = False) -> DatasetSummary:
    """Copy the dataset `src` to `dst` with next_obs/<key> for every obs key of every demo."""
    validate_dataset(src)
    if os.path.abspath(src) == os.path.abspath(dst):
        raise DatasetError(f"{dst}: the export must not overwrite its input", reason="OUTPUT_EXISTS")
    if os.path.exists(dst) and not overwrite:
        raise DatasetError(f"{dst} exists; choose another output", reason="OUTPUT_EXISTS")
    os.makedirs(os.path.dirname(os.path.abspath(dst)), exist_ok=True)
    tmp = f"{dst}.writing"
    shutil.copyfile(src, tmp)
    try:
        with h5py.File(tmp, "r+") as f:
            for name in f["data"]:
                g = f["data"][name]
                if "next_obs" in g:
                    del g["next_obs"]
                nxt = g.create_group("next_obs")
                for k in sorted(g["obs"]):
                    ds = g["obs"][k]
                    kw = {"compression": ds.compression, "compression_opts": ds.compression_opts,
                          "chunks": ds.chunks} if ds.compression else {}
                    nxt.create_dataset(k, data=next_observations(ds[()]), track_times=False, **kw)
        os.replace(tmp, dst)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return validate_dataset(dst)

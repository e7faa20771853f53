"""Normalization statistics that travel with a checkpoint (JSON-able lists, not tensors).

Observations: mean/std per low-dim key, with robomimic's +1e-3 on the std
(robomimic/utils/dataset.py `_compute_traj_stats` / `normalize_obs`), so a constant
dimension (a fixed peg) does not blow up. Initiation targets: min-max to [-1, 1] as Diffusion
Policy's `LinearNormalizer` (range_eps 1e-4: a constant dimension maps to -1), which HSP-Reg's
appendix cites.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import InvalidInputError

STD_EPS = 1e-3  # robomimic
RANGE_EPS = 1e-4  # Diffusion Policy


@dataclass(frozen=True)
class ObsStats:
    """Per-key mean and std of the low-dim observations over the training demos."""

    mean: Mapping[str, tuple[float, ...]]
    std: Mapping[str, tuple[float, ...]]

    @staticmethod
    def fit(arrays: Mapping[str, np.ndarray]) -> "ObsStats":
        """arrays: key -> (N, D) rows of every training step."""
        mean, std = {}, {}
        for k, a in arrays.items():
            a = np.asarray(a, float).reshape(len(a), -1)
            if len(a) == 0:
                raise InvalidInputError(f"no rows to fit normalization of {k!r}")
            mean[k] = tuple(float(x) for x in a.mean(0))
            std[k] = tuple(float(x) for x in a.std(0) + STD_EPS)
        return ObsStats(mean, std)

    def normalize(self, key: str, a: np.ndarray) -> np.ndarray:
        return (np.asarray(a, float) - np.asarray(self.mean[key])) / np.asarray(self.std[key])

    def to_json(self) -> dict:
        return {"mean": {k: list(v) for k, v in self.mean.items()}, "std": {k: list(v) for k, v in self.std.items()}}

    @staticmethod
    def from_json(d: Mapping) -> "ObsStats":
        return ObsStats({k: tuple(v) for k, v in d["mean"].items()}, {k: tuple(v) for k, v in d["std"].items()})


@dataclass(frozen=True)
class MinMax:
    """x -> scale * x + offset maps [min, max] onto [-1, 1] per dimension."""

    scale: tuple[float, ...]
    offset: tuple[float, ...]

    @staticmethod
    def fit(x: np.ndarray) -> "MinMax":
        x = np.asarray(x, float).reshape(len(x), -1)
        if len(x) == 0:
            raise InvalidInputError("no rows to fit the [-1, 1] normalization")
        lo, hi = x.min(0), x.max(0)
        rng = hi - lo
        rng = np.where(rng < RANGE_EPS, 2.0, rng)  # constant dimension: scale 1, maps to -1
        scale = 2.0 / rng
        offset = -1.0 - scale * lo
        return MinMax(tuple(map(float, scale)), tuple(map(float, offset)))

    def normalize(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(x, float) * np.asarray(self.scale) + np.asarray(self.offset)

    def unnormalize(self, y: np.ndarray) -> np.ndarray:
        return (np.asarray(y, float) - np.asarray(self.offset)) / np.asarray(self.scale)

    def to_json(self) -> dict:
        return {"scale": list(self.scale), "offset": list(self.offset)}

    @staticmethod
    def from_json(d: Mapping) -> "MinMax":
        return MinMax(tuple(d["scale"]), tuple(d["offset"]))

"""Reading a generated dataset for training: split, statistics, and the samples each network sees.

robomimic semantics: the train/valid split is by demo and lives in the file as the filter keys
`mask/train` and `mask/valid` (robomimic/scripts/split_train_val.py; written once, reused after,
seeded here so it is reproducible). π is trained on windows of `seq_length` steps starting at
every step, padded at the end by repeating the last step (SequenceDataset with
pad_seq_length=True, pad_same). For HSP the windows stay inside one skill segment
(`labels/mp_step == 0`), so π never sees motion-planner steps; the MimicGen baseline uses whole
demos. T sees single steps with `termination_labels`. HSP-Class and HSP-Reg see the observations
"at the end of the previous skill": the first `initiation_window` steps of each motion segment
(the steps T is trained to call "terminate"), labelled with that motion's source demo and target.
"""
from __future__ import annotations

import hashlib
import json
import logging
from dataclasses import dataclass
from typing import Sequence

import h5py
import numpy as np

from ..errors import InvalidInputError, ParameterError
from ..tasks import get_task
from .config import REG_TARGETS
from .normalization import MinMax, ObsStats
from .observation import DERIVED_FROM, DERIVED_KEYS, add_derived, derived_shapes
from .rotation import pose_to_pos_rot6d
from .termination import segments, settled_tail, termination_labels


log = logging.getLogger("skillgen.train")


class DatasetReadError(InvalidInputError):
    reason = "BAD_DATASET"


@dataclass(frozen=True)
class DatasetInfo:
    task: str
    variant: str
    method: str
    augmented: bool
    object_ids: tuple[str, ...]
    skills: tuple[str, ...]
    demos: tuple[str, ...]
    obs_shapes: dict  # key -> per-step shape
    num_source_demos: int  # max source_demo label + 1


def _demo_names(f: h5py.File) -> tuple[str, ...]:
    return tuple(sorted(f["data"], key=lambda k: int(k[5:])))


def dataset_info(path: str) -> DatasetInfo:
    try:
        with h5py.File(path, "r", locking=False) as f:
            env = json.loads(f["data"].attrs["env_args"])
            names = _demo_names(f)
            if not names:
                raise DatasetReadError(f"{path} holds no demos")
            g = f["data"][names[0]]
            shapes = {k: tuple(g["obs"][k].shape[1:]) for k in g["obs"]}
            shapes.update(derived_shapes(shapes))
            methods = {str(f["data"][n].attrs.get("method", env.get("generation", {}).get("method", "skillgen")))
                       for n in names}
            src = max(int(f["data"][n]["labels/source_demo"][()].max(initial=-1)) for n in names) + 1
    except (OSError, KeyError, ValueError) as e:
        raise DatasetReadError(f"cannot read dataset {path}: {e}")
    if len(methods) != 1:
        raise DatasetReadError(f"{path} mixes generation methods {sorted(methods)}")
    gen = env.get("generation", {})
    task = get_task(env["env_name"])
    return DatasetInfo(task=task.name, variant=env.get("env_kwargs", {}).get("variant", ""), method=methods.pop(),
                       augmented=bool(gen.get("augment", False)),
                       object_ids=tuple(env.get("env_kwargs", {}).get("object_ids", ())),
                       skills=tuple(s.name for s in task.skills), demos=names, obs_shapes=shapes,
                       num_source_demos=max(src, 1))


def file_sha256(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def split_train_valid(path: str, valid_ratio: float, seed: int) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The split stored in mask/train + mask/valid; written (seeded, robomimic's rule:
    int(ratio * N) validation demos) when the file has none yet. A read-only file gets the same
    split without it being stored."""
    with h5py.File(path, "r", locking=False) as f:
        names = _demo_names(f)
        m = f.get("mask", {})
        if "train" in m and "valid" in m:
            train = tuple(n.decode() for n in m["train"][()])
            valid = tuple(n.decode() for n in m["valid"][()])
            if set(train) | set(valid) != set(names) or set(train) & set(valid):
                raise DatasetReadError(f"{path}: mask/train and mask/valid do not partition the demos")
            return train, valid
    num_valid = int(valid_ratio * len(names))
    perm = np.random.default_rng(seed).permutation(len(names))
    valid = tuple(sorted((names[i] for i in perm[:num_valid]), key=lambda k: int(k[5:])))
    train = tuple(n for n in names if n not in valid)
    try:
        with h5py.File(path, "a", locking=False) as f:
            m = f.require_group("mask")
            for key, val in (("train", train), ("valid", valid)):
                m.create_dataset(key, data=np.array([n.encode() for n in val], dtype="S"), track_times=False)
    except OSError as e:
        log.warning("could not store the split in %s (%s); using it unstored", path, e)
    return train, valid


@dataclass
class DemoArrays:
    obs: dict  # key -> (T, ...)
    actions: np.ndarray
    mp_step: np.ndarray
    source_demo: np.ndarray
    initiation_target: np.ndarray
    augmented: np.ndarray | None = None  # (T,) 1 on initiation augmentation's recovery steps


def reg_target(d: DemoArrays, a: int, kind: str = "nominal") -> np.ndarray:
    """(7,) HSP-Reg's target for the motion segment starting at step a.

    "initiation_target": the stored label, the pose the motion went to; with initiation augmentation
    that is the *perturbed* pose (uniform +-8 cm, up to 80 deg), i.e. noise around the skill's start.
    "nominal": the initiation state T_W^{E_0} before the perturbation, where the skill's recovery
    segment ends: the EE pose at the first non-augmented step of the skill that follows (the stored
    label when that skill has no recovery steps). The paper's I "predicts initiation states T_W^{E_0}"
    and trains on augmented data so that pi is "robust to incorrect initiation pose predictions"
    (Appendix "Initiation Augmentation"): noise in I's targets would only teach it the noise."""
    if kind not in REG_TARGETS:
        raise ParameterError(f"unknown reg target {kind!r}; known: {list(REG_TARGETS)}", reason="INVALID_PARAMETER")
    if kind == "initiation_target" or d.augmented is None or not {"robot0_eef_pos", "robot0_eef_quat"} <= set(d.obs):
        return d.initiation_target[a]
    mp = np.asarray(d.mp_step) != 0
    b = next((e for s, e in segments(mp) if s == a), a)  # the motion from a ends where its skill starts
    c = next((e for s, e in segments(~mp) if s == b), b)
    recovery = np.asarray(d.augmented[b:c]) != 0
    if not len(recovery) or not recovery[0] or recovery.all():  # no skill, no recovery, or no end to it
        return d.initiation_target[a]
    i = b + int(np.argmin(recovery))  # the skill's first non-augmented step
    return np.concatenate([d.obs["robot0_eef_pos"][i], d.obs["robot0_eef_quat"][i]]).astype(float)


def read_demos(path: str, names: Sequence[str], keys: Sequence[str]) -> list[DemoArrays]:
    """Each named demo's obs `keys` (DERIVED_KEYS computed from the stored ones), actions and labels."""
    out = []
    derive = any(k in DERIVED_KEYS for k in keys)
    # each stored key read once: the requested ones, plus what the derived ones are computed from
    stored = dict.fromkeys([k for k in keys if k not in DERIVED_KEYS] + (list(DERIVED_FROM) if derive else []))
    with h5py.File(path, "r", locking=False) as f:
        for n in names:
            g = f["data"][n]
            try:
                obs = {k: g["obs"][k][()] for k in stored}
                if derive:
                    obs = {k: v for k, v in add_derived(obs).items() if k in keys}
                out.append(DemoArrays(obs, g["actions"][()].astype(np.float32),
                                      g["labels/mp_step"][()], g["labels/source_demo"][()],
                                      g["labels/initiation_target"][()],
                                      g["labels/augmented"][()] if "augmented" in g["labels"] else None))
            except KeyError as e:
                raise DatasetReadError(f"{path}/{n} lacks {e}")
    return out


def _settled(d: DemoArrays) -> np.ndarray:
    """The "settled" rule's skill tails (termination.settled_tail) from the demo's raw hand and fingers."""
    need = ("robot0_eef_pos", "robot0_eef_quat", "robot0_gripper_qpos")
    if not set(need) <= set(d.obs):
        raise DatasetReadError(f"termination_labels 'settled' needs {list(need)} among the observations")
    return settled_tail(d.mp_step, *(d.obs[k] for k in need))


def fit_obs_stats(demos: Sequence[DemoArrays], low_dim_keys: Sequence[str]) -> ObsStats:
    return ObsStats.fit({k: np.concatenate([d.obs[k].reshape(len(d.actions), -1) for d in demos])
                         for k in low_dim_keys})


def initiation_indices(mp_step: np.ndarray, window: int) -> list[tuple[int, int]]:
    """(step, motion segment start) for the first min(window, ceil(L/2)) steps of each motion segment."""
    out = []
    for a, b in segments(np.asarray(mp_step) != 0):
        out += [(i, a) for i in range(a, a + min(window, (b - a + 1) // 2))]
    return out


def fit_initiation_norm(demos: Sequence[DemoArrays], kind: str = "nominal") -> MinMax:
    targets = [pose_to_pos_rot6d(reg_target(d, a, kind)) for d in demos for a, _ in segments(d.mp_step != 0)]
    return MinMax.fit(np.array(targets))


class TrainingSet:
    """All samples of one split as flat arrays (low-dim normalized float32, images uint8)."""

    def __init__(self, demos: Sequence[DemoArrays], low_dim_keys: Sequence[str], image_keys: Sequence[str],
                 stats: ObsStats, seq_length: int, all_steps: bool, init_window: int, init_norm: MinMax | None,
                 reg_kind: str = "nominal", term_rule: str = "paper"):
        if not demos:
            raise DatasetReadError("no demos in this split")
        self.obs = {k: np.concatenate([stats.normalize(k, d.obs[k].reshape(len(d.actions), -1))
                                       for d in demos]).astype(np.float32) for k in low_dim_keys}
        self.obs.update({k: np.concatenate([d.obs[k] for d in demos]).astype(np.uint8) for k in image_keys})
        self.actions = np.concatenate([d.actions for d in demos])
        self.term = np.concatenate([termination_labels(d.mp_step, _settled(d) if term_rule == "settled" else None)
                                    for d in demos])
        starts, ends, init_idx, init_cls, init_tgt = [], [], [], [], []
        off = 0
        for d in demos:
            n = len(d.actions)
            segs = [(0, n)] if all_steps else segments(d.mp_step == 0)
            for a, b in segs:
                starts.append(np.arange(off + a, off + b))
                ends.append(np.full(b - a, off + b))
            targets = {}
            for i, a in initiation_indices(d.mp_step, init_window):
                init_idx.append(off + i)
                init_cls.append(int(d.source_demo[a]))
                if a not in targets:
                    targets[a] = pose_to_pos_rot6d(reg_target(d, a, reg_kind))
                init_tgt.append(targets[a])
            off += n
        self.size = off
        self.win_start = np.concatenate(starts) if starts else np.zeros(0, int)
        self.win_end = np.concatenate(ends) if ends else np.zeros(0, int)
        if len(self.win_start) == 0:
            raise DatasetReadError("no policy steps to train on (no skill steps in these demos)")
        self.seq_length = seq_length
        self.init_idx = np.array(init_idx, dtype=np.int64)
        self.init_cls = np.array(init_cls, dtype=np.int64)
        tgt = np.array(init_tgt).reshape(-1, 9)
        self.init_tgt = (init_norm.normalize(tgt) if init_norm else tgt).astype(np.float32)

    def windows(self, rows: np.ndarray) -> np.ndarray:
        """(B,) window indices -> (B, seq) step indices, the tail padded with the segment's last step."""
        idx = self.win_start[rows, None] + np.arange(self.seq_length)[None]
        return np.minimum(idx, self.win_end[rows, None] - 1)

    def take(self, idx: np.ndarray) -> dict[str, np.ndarray]:
        return {k: v[idx] for k, v in self.obs.items()}

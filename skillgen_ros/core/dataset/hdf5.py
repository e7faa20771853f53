"""Generated datasets in robomimic's HDF5 layout (documented in docs/dataset.md).

    data/                  attrs: total (int), env_args (JSON str)
      demo_N/              attrs: num_samples, method, index, scene_seed, source_demos, reason, ...
        obs/<key>          (T, ...)  robot0_eef_pos, robot0_eef_quat, robot0_gripper_qpos,
                                     robot0_joint_pos, object, <id>_pose, [<id>_joints], [<camera>_image]
        actions            (T, 7)   normalized delta pose + gripper
        actions_abs        (T, 8)   absolute pose (xyz, xyzw) + gripper
        states, rewards, dones
        next_obs/<key>     (T, ...) only in `skillgen dataset export --format robomimic-next-obs` copies
        labels/<key>       (T, ...) mp_step, skill_index, source_demo, initiation_target, augmented
        estimates/         (E, ...) perception's estimates as events: step, stamp, <id>_pose (optional)
    mask/<filter_key>      (M,) demo names, e.g. "successful", "source_0", a failure reason

Demos are appended one at a time and the file is flushed after each, so a run that dies
leaves a valid file with every demo written so far. Datasets carry no timestamps, so the same
attempts give the same bytes.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import Sequence

import h5py
import numpy as np

from ..errors import SkillGenError
from ..generation.episode import Episode

OBS_KEYS = ("robot0_eef_pos", "robot0_eef_quat", "robot0_gripper_qpos", "robot0_joint_pos", "object")
LABEL_KEYS = ("mp_step", "skill_index", "source_demo", "initiation_target", "augmented")
LABEL_DIMS = {"initiation_target": 7}
OBS_DIMS = {"robot0_eef_pos": 3, "robot0_eef_quat": 4}
# HDF5 keeps in memory what it learnt of every object created while a file is open (its metadata
# cache grows to 32 MiB per file): a writer that stays open for a 1000-attempt run grew ~0.1 MiB per
# demo (issue 19's soak). Closing and reopening every REOPEN_EVERY demos keeps it flat.
REOPEN_EVERY = 25


class DatasetError(SkillGenError):
    reason = "BAD_DATASET"


def _names(names: Sequence[str]) -> np.ndarray:
    return np.array([n.encode() for n in names], dtype="S") if names else np.zeros(0, dtype="S1")


def _attr(v):
    """HDF5 attributes take scalars, strings and flat numeric lists; anything else goes in as JSON."""
    if isinstance(v, (bool, np.bool_)):
        return int(v)
    if isinstance(v, (int, float, str, np.integer, np.floating)):
        return v
    if isinstance(v, (list, tuple)) and all(isinstance(x, (int, float, np.integer, np.floating)) for x in v) and v:
        return np.asarray(v)
    return json.dumps(v, sort_keys=True, default=str)


class DatasetWriter:
    """Append-only writer. mode: "create" (fail if the file exists), "overwrite" or "append"."""

    def __init__(self, path: str, env_args: dict, mode: str = "create", compress_images: bool = True,
                 allow_empty: bool = False):
        if mode not in ("create", "overwrite", "append"):
            raise DatasetError(f"unknown writer mode {mode!r}", reason="INVALID_PARAMETER")
        self.path = str(path)
        d = os.path.dirname(os.path.abspath(self.path))
        try:
            os.makedirs(d, exist_ok=True)
        except OSError as e:
            raise DatasetError(f"cannot create output directory {d}: {e.strerror}", reason="OUTPUT_NOT_WRITABLE") from e
        if not os.access(d, os.W_OK):
            raise DatasetError(f"output directory {d} is not writable", reason="OUTPUT_NOT_WRITABLE")
        if mode == "create" and os.path.exists(self.path):
            raise DatasetError(f"{self.path} exists; choose another output or overwrite", reason="OUTPUT_EXISTS")
        self.compress_images = compress_images
        self.allow_empty = allow_empty  # the failed-attempts file keeps attempts that failed before moving
        h5mode = "a" if mode == "append" and os.path.exists(self.path) else "w"
        try:
            self._f = h5py.File(self.path, h5mode)  # default libver: no consistency flag a crash would leave set
        except OSError as e:
            raise DatasetError(f"cannot open {self.path}: {e}", reason="OUTPUT_NOT_WRITABLE") from e
        if h5mode == "w":
            data = self._f.create_group("data", track_order=True)
            data.attrs["total"] = 0
            data.attrs["env_args"] = json.dumps(env_args, sort_keys=True)
            self._f.create_group("mask")
        self._data = self._f["data"]
        self._masks = {k: [n.decode() for n in self._f["mask"][k][()]] for k in self._f["mask"]}
        self._next = 1 + max((int(k.split("_")[1]) for k in self._data), default=-1)
        self._appended = 0
        self._f.flush()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    @property
    def num_demos(self) -> int:
        return len(self._data)

    def _ds(self, group, name: str, arr: np.ndarray) -> None:
        arr = np.asarray(arr)
        kw = {}
        if arr.dtype == np.uint8 and arr.ndim == 4 and self.compress_images:
            kw = {"compression": "gzip", "compression_opts": 4, "chunks": (1, *arr.shape[1:])}
        group.create_dataset(name, data=arr, track_times=False, **kw)

    def append(self, episode: Episode, attrs: dict | None = None, filter_keys: Sequence[str] = ()) -> str:
        """Write one demo, update `total` and the filter keys, flush; returns the demo's name."""
        if episode.num_samples == 0 and not self.allow_empty:
            raise DatasetError("refusing to write an episode with no steps", reason="EMPTY_EPISODE")
        name = f"demo_{self._next}"
        g = self._data.create_group(name)
        obs = g.create_group("obs")
        for k in sorted(episode.obs):
            self._ds(obs, k, episode.obs[k])
        for k, v in (("actions", episode.actions), ("actions_abs", episode.actions_abs), ("states", episode.states),
                     ("rewards", episode.rewards), ("dones", episode.dones)):
            self._ds(g, k, v)
        lab = g.create_group("labels")
        for k in sorted(episode.labels):
            self._ds(lab, k, episode.labels[k])
        if episode.estimates:
            est = g.create_group("estimates")
            for k in sorted(episode.estimates):
                self._ds(est, k, episode.estimates[k])
        g.attrs["num_samples"] = episode.num_samples
        g.attrs["object_ids"] = json.dumps(list(episode.object_ids))
        for k, v in sorted((attrs or {}).items()):
            g.attrs[k] = _attr(v)
        self._data.attrs["total"] = int(self._data.attrs["total"]) + episode.num_samples
        for key in filter_keys:
            self._masks.setdefault(key, []).append(name)
            if key in self._f["mask"]:
                del self._f["mask"][key]
            self._f["mask"].create_dataset(key, data=_names(self._masks[key]), track_times=False)
        self._next += 1
        self._f.flush()
        self._appended += 1
        if self._appended % REOPEN_EVERY == 0:
            self._f.close()
            self._f = h5py.File(self.path, "a")
            self._data = self._f["data"]
        return name

    def close(self) -> None:
        if self._f.id.valid:
            self._f.flush()
            self._f.close()


@dataclass(frozen=True)
class DatasetSummary:
    path: str
    num_demos: int
    total: int
    filter_keys: dict  # key -> number of demos
    env_args: dict


def validate_dataset(path: str) -> DatasetSummary:
    """Check the documented layout; raise DatasetError naming the file, demo and field that is wrong."""
    try:
        f = h5py.File(path, "r", locking=False)  # readable while a run still writes it
    except OSError as e:
        raise DatasetError(f"{path}: not a readable HDF5 file: {e}") from e
    with f:
        def bad(msg):
            return DatasetError(f"{path}: {msg}")

        if "data" not in f:
            raise bad("no 'data' group")
        data = f["data"]
        for a in ("total", "env_args"):
            if a not in data.attrs:
                raise bad(f"data lacks attribute {a!r}")
        try:
            env_args = json.loads(data.attrs["env_args"])
        except (TypeError, ValueError) as e:
            raise bad(f"data.attrs['env_args'] is not JSON: {e}") from e
        total = 0
        for name in data:
            g = data[name]
            if not name.startswith("demo_"):
                raise bad(f"unexpected group data/{name}")
            if "num_samples" not in g.attrs:
                raise bad(f"{name} lacks attribute num_samples")
            T = int(g.attrs["num_samples"])
            shapes = {"actions": (T, 7), "actions_abs": (T, 8), "rewards": (T,), "dones": (T,)}
            for k, shp in shapes.items():
                if k not in g or g[k].shape != shp:
                    raise bad(f"{name}/{k} missing or not shaped {shp}")
            if "states" not in g or g["states"].shape[0] != T:
                raise bad(f"{name}/states missing or not {T} rows")
            a = g["actions"][()]
            if not np.all(np.isfinite(a)) or np.abs(a[:, :6]).max(initial=0) > 1.0 + 1e-9:
                raise bad(f"{name}/actions has NaN or pose values outside [-1, 1]")
            for grp, keys, dims in (("obs", OBS_KEYS, OBS_DIMS), ("labels", LABEL_KEYS, LABEL_DIMS)):
                if grp not in g:
                    raise bad(f"{name} lacks group {grp}/")
                for k in keys:
                    if k not in g[grp]:
                        raise bad(f"{name}/{grp} lacks {k}")
                    ds = g[grp][k]
                    if ds.shape[0] != T or (k in dims and ds.shape[1:] != (dims[k],)):
                        raise bad(f"{name}/{grp}/{k} has shape {ds.shape}, expected {T} rows"
                                  + (f" of {dims[k]}" if k in dims else ""))
                for k in g[grp]:
                    if g[grp][k].shape[0] != T:
                        raise bad(f"{name}/{grp}/{k} has {g[grp][k].shape[0]} rows, expected {T}")
            if "next_obs" in g:  # robomimic's offline-RL layout (next_obs.py): one per obs key, same shapes
                if set(g["next_obs"]) != set(g["obs"]) or any(g["next_obs"][k].shape != g["obs"][k].shape
                                                              for k in g["obs"]):
                    raise bad(f"{name}/next_obs does not mirror {name}/obs (keys and shapes)")
            if "estimates" in g:
                _check_estimates(g["estimates"], T, bad, name)
            total += T
        if total != int(data.attrs["total"]):
            raise bad(f"data.attrs['total'] = {int(data.attrs['total'])} but demos hold {total} samples")
        keys = {}
        if "mask" in f:
            for k in f["mask"]:
                names = [n.decode() for n in f["mask"][k][()]]
                missing = [n for n in names if n not in data]
                if missing:
                    raise bad(f"mask/{k} names missing demos {missing[:3]}")
                keys[k] = len(names)
        return DatasetSummary(str(path), len(data), total, keys, env_args)


def _check_estimates(est, T: int, bad, name: str) -> None:
    """estimates/: step (E,) ints in [0, T], stamp (E,), <id>_pose (E, 7) (NaN rows: not estimated)."""
    for k in ("step", "stamp"):
        if k not in est or est[k].ndim != 1:
            raise bad(f"{name}/estimates lacks {k} (E,)")
    E = est["step"].shape[0]
    steps = est["step"][()]
    if steps.dtype.kind not in "iu" or np.any(steps < 0) or np.any(steps > T) or np.any(np.diff(steps) < 0):
        raise bad(f"{name}/estimates/step must be non-decreasing integers in [0, {T}]")
    for k in est:
        if k in ("step", "stamp"):
            if est[k].shape != (E,):
                raise bad(f"{name}/estimates/{k} has shape {est[k].shape}, expected ({E},)")
        elif not k.endswith("_pose") or est[k].shape != (E, 7):
            raise bad(f"{name}/estimates/{k} is not an <id>_pose of shape ({E}, 7)")


def _attr_value(v):
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    return v


def read_episode(path: str, demo: str) -> tuple[Episode, dict]:
    """One demo back as an Episode plus its attributes (JSON-valued ones stay strings)."""
    with h5py.File(path, "r", locking=False) as f:
        if f"data/{demo}" not in f:
            raise DatasetError(f"{path}: no demo {demo!r}", reason="UNKNOWN_DEMO")
        g = f[f"data/{demo}"]
        attrs = {k: _attr_value(v) for k, v in g.attrs.items()}
        ids = tuple(json.loads(attrs.pop("object_ids", "[]")))
        attrs.pop("num_samples", None)
        ep = Episode(obs={k: g["obs"][k][()] for k in g["obs"]}, actions=g["actions"][()],
                     actions_abs=g["actions_abs"][()], states=g["states"][()], rewards=g["rewards"][()],
                     dones=g["dones"][()], labels={k: g["labels"][k][()] for k in g["labels"]}, object_ids=ids,
                     estimates={k: g["estimates"][k][()] for k in g["estimates"]} if "estimates" in g else {})
    return ep, attrs


def merge_datasets(inputs: Sequence[str], output: str, mode: str = "create", keep=None,
                   unique: bool = False) -> DatasetSummary:
    """Merge shards into one file, demos ordered by their attempt index (as one run would write
    them), filter keys carried over. env_args come from the first shard. keep(index) -> bool
    selects demos; unique=True refuses an attempt index found twice (DUPLICATE_INDEX)."""
    entries = []
    env_args = None
    for p in inputs:
        s = validate_dataset(p)
        env_args = s.env_args if env_args is None else env_args
        with h5py.File(p, "r", locking=False) as f:
            keys_of: dict[str, list[str]] = {}
            for k in f["mask"]:
                for n in f["mask"][k][()]:
                    keys_of.setdefault(n.decode(), []).append(k)
            for name in f["data"]:
                idx = int(f["data"][name].attrs.get("index", -1))
                if keep is not None and not keep(idx):
                    continue
                entries.append((idx, p, name, sorted(keys_of.get(name, []))))
    entries.sort(key=lambda e: (e[0], e[1], int(e[2][5:])))
    if unique:
        from collections import Counter

        dup = sorted(i for i, n in Counter(e[0] for e in entries).items() if n > 1)
        if dup:
            raise DatasetError(f"attempt indices {dup[:5]} appear more than once in {list(inputs)}",
                               reason="DUPLICATE_INDEX")
    with DatasetWriter(output, env_args or {}, mode, allow_empty=True) as w:
        for _, p, name, keys in entries:
            ep, attrs = read_episode(p, name)
            w.append(ep, attrs, keys)
    return validate_dataset(output)

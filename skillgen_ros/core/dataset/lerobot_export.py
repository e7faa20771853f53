"""LeRobot export: a generated robomimic-layout HDF5 as a LeRobotDataset (parquet + mp4 + meta/).

Many users train with LeRobot (Isaac Lab users ask for this export in IsaacLab#2739). The files
are written by lerobot's own writer (LeRobotDataset.create, add_frame, save_episode, finalize),
so they are in whatever format the installed lerobot writes (codebase v3.0 for lerobot 0.4.4),
never a hand-made copy of it. One demo is one episode, one step one frame, at the dataset's
control rate (env_args.env_kwargs.control_freq, 20 Hz). The mapping (docs/dataset.md "LeRobot"):

    obs/robot0_{eef_pos,eef_quat,gripper_qpos,joint_pos}  -> observation.state (concatenated, float32)
    obs/object                                            -> observation.environment_state (float32)
    obs/<camera>_image                                    -> observation.images.<camera> (video)
    any other low-dim obs/<key> (not <id>_pose)           -> observation.<key> (float32)
    actions                                               -> action (float32)
    actions_abs, states                                   -> absolute_action, sim_state (float32)
    rewards, dones                                        -> next.reward (float32), next.done (bool)
    labels/<key> (the HSP labels)                         -> labels.<key> (their own dtype)
    env_args, each demo's name and attributes             -> meta/skillgen.json

obs/<id>_pose are slices of obs/object (named per object in environment_state's names) and are not
repeated; estimates/ (E events per demo, not per step) stay in the HDF5 only. Zero-step demos
(attempts that failed before moving) are skipped: LeRobot has no empty episodes.

The export is written into `<out>.writing` and renamed to `<out>` when lerobot has finalized it;
a failure part-way removes it, so `<out>` is either absent or a whole dataset.
"""
from __future__ import annotations

import json
import os
import shutil
import warnings
from contextlib import contextmanager
from dataclasses import dataclass

import h5py
import numpy as np
from tqdm import tqdm

from .hdf5 import OBS_KEYS, DatasetError, _attr_value, validate_dataset
from .lerobot_import import codebase_version, lerobot_dataset_class

STATE_KEYS = tuple(k for k in OBS_KEYS if k.startswith("robot0_"))  # the robot's proprioception, in order
# Names of observation.state's entries; the other state keys are named <key without robot0_>_<i>.
STATE_NAMES = {"robot0_eef_pos": ("eef_x", "eef_y", "eef_z"),
               "robot0_eef_quat": ("eef_qx", "eef_qy", "eef_qz", "eef_qw")}
POSE_NAMES = ("x", "y", "z", "qx", "qy", "qz", "qw")
ACTION_NAMES = ("dx", "dy", "dz", "drx", "dry", "drz", "gripper")  # docs/dataset.md "Actions"
ABS_ACTION_NAMES = POSE_NAMES + ("gripper",)
IMAGE_SUFFIX = "_image"
ROBOT_TYPE = "panda"
META_FILE = "meta/skillgen.json"


@dataclass(frozen=True)
class Column:
    """One LeRobot feature and where its values come from in a demo group."""

    feature: str
    sources: tuple[str, ...]  # demo-relative HDF5 paths, concatenated along the last axis
    dtype: str  # numpy dtype name, or "video"
    shape: tuple[int, ...]
    names: tuple[str, ...] | None

    def spec(self) -> dict:
        names = ("height", "width", "channels") if self.dtype == "video" else self.names
        return {"dtype": self.dtype, "shape": self.shape, "names": list(names) if names else None}


@dataclass(frozen=True)
class LeRobotSummary:
    path: str
    episodes: int
    frames: int
    fps: int
    features: tuple[str, ...]
    video_keys: tuple[str, ...]
    codebase_version: str
    skipped_empty: tuple[str, ...]  # demos with no steps


def _ordered_demos(data) -> list[str]:
    return sorted(data, key=lambda k: int(k[5:]))


def _row_shape(ds) -> tuple[int, ...]:
    return tuple(int(n) for n in ds.shape[1:]) or (1,)


def plan_columns(f: h5py.File, demos: list[str]) -> list[Column]:
    """The features of the export, from the first demo; every other demo must match it."""
    g = f["data"][demos[0]]
    obs = g["obs"]
    state_names: list[str] = []
    for k in STATE_KEYS:
        n = _row_shape(obs[k])[0]
        state_names += STATE_NAMES.get(k, tuple(f"{k.removeprefix('robot0_')}_{i}" for i in range(n)))
    ids = json.loads(g.attrs.get("object_ids", "[]"))
    env_names = tuple(f"{i}_{c}" for i in ids for c in POSE_NAMES)
    n_env = _row_shape(obs["object"])[0]
    cols = [Column("observation.state", tuple(f"obs/{k}" for k in STATE_KEYS), "float32", (len(state_names),),
                   tuple(state_names)),
            Column("observation.environment_state", ("obs/object",), "float32", (n_env,),
                   env_names if len(env_names) == n_env else None)]
    for k in sorted(obs):
        if k.endswith(IMAGE_SUFFIX) and obs[k].ndim == 4 and obs[k].dtype == np.uint8:
            cols.append(Column(f"observation.images.{k[:-len(IMAGE_SUFFIX)]}", (f"obs/{k}",), "video",
                               _row_shape(obs[k]), None))
        elif k not in STATE_KEYS and k != "object" and not k.endswith("_pose") and obs[k].ndim <= 2:
            cols.append(Column(f"observation.{k}", (f"obs/{k}",), "float32", _row_shape(obs[k]), None))
    cols += [Column("action", ("actions",), "float32", (7,), ACTION_NAMES),
             Column("absolute_action", ("actions_abs",), "float32", (8,), ABS_ACTION_NAMES),
             Column("sim_state", ("states",), "float32", _row_shape(g["states"]), None),
             Column("next.reward", ("rewards",), "float32", (1,), None),
             Column("next.done", ("dones",), "bool", (1,), None)]
    for k in sorted(g["labels"]):
        ds = g["labels"][k]
        cols.append(Column(f"labels.{k}", (f"labels/{k}",), np.dtype(ds.dtype).name, _row_shape(ds), None))
    for name in demos[1:]:
        _check_matches(f, name, demos[0], cols)
    return cols


def _check_matches(f: h5py.File, name: str, first: str, cols: list[Column]) -> None:
    """LeRobot has one feature set per dataset: demo `name` must give every column its shape."""
    g = f["data"][name]
    for c in cols:
        if all(s in g for s in c.sources):
            rows = [_row_shape(g[s]) for s in c.sources]
            shape = rows[0] if c.dtype == "video" else (sum(int(np.prod(r)) for r in rows),)
            if shape == c.shape or (c.dtype != "video" and shape[0] == int(np.prod(c.shape))):
                continue
        raise DatasetError(f"{f.filename}: {name} does not match {first} in {c.feature} ({', '.join(c.sources)}); "
                           "a LeRobot dataset has one shape per feature", reason="BAD_DATASET")


def _episode_arrays(g, cols: list[Column]) -> dict[str, np.ndarray]:
    """Each column's (T, ...) array for one demo, in the column's dtype."""
    out = {}
    for c in cols:
        if c.dtype == "video":
            out[c.feature] = g[c.sources[0]][()]
            continue
        parts = [np.asarray(g[s][()]).reshape(len(g[s]), -1) for s in c.sources]
        out[c.feature] = np.concatenate(parts, axis=1).astype(c.dtype).reshape((-1,) + c.shape)
    return out


def _check_paths(src: str, dst: str) -> None:
    if not os.path.isfile(src):
        raise DatasetError(f"{src}: no such file", reason="INPUT_NOT_FOUND")
    if os.path.exists(dst) and not (os.path.isdir(dst) and not os.listdir(dst)):
        raise DatasetError(f"{dst} exists and is not an empty directory; choose another output",
                           reason="OUTPUT_EXISTS")


@contextmanager
def scheduling_kept():
    """Restore the calling thread's scheduling policy on exit. SVT-AV1 (libsvtav1, LeRobot's default video codec),
    run as root, switches the thread that encodes to SCHED_FIFO priority 99 ("Failed to set thread priority"
    warnings aside): every process started from it afterwards (a node, a worker) inherited real-time priority
    and starved the rest of the machine. The suite's node tests ran 3-6x slower after the LeRobot test."""
    if not hasattr(os, "sched_getscheduler"):
        yield
        return
    policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    try:
        yield
    finally:
        if (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority) != (policy, param.sched_priority):
            os.sched_setscheduler(0, policy, param)


def export_lerobot(src: str, dst: str, repo_id: str | None = None, vcodec: str | None = None,
                   progress: bool = False) -> LeRobotSummary:
    """Write the demos of `src` as a LeRobotDataset in the directory `dst` (absent or empty).

    `vcodec` is lerobot's video codec (None: lerobot's default, libsvtav1); `progress` shows a bar over the demos."""
    _check_paths(src, dst)
    summary = validate_dataset(src)  # BAD_DATASET: not our layout
    LeRobotDataset = lerobot_dataset_class()  # LEROBOT_NOT_INSTALLED
    env_args = summary.env_args
    try:
        fps = int(env_args["env_kwargs"]["control_freq"])
    except (KeyError, TypeError, ValueError) as e:
        raise DatasetError(f"{src}: env_args lacks env_kwargs.control_freq (the frame rate)") from e
    task = str(env_args.get("env_name", "task"))
    repo_id = repo_id or f"skillgen_ros/{task}_{env_args['env_kwargs'].get('variant', 'D0')}"
    tmp = os.path.abspath(dst).rstrip(os.sep) + ".writing"
    if os.path.exists(tmp):
        shutil.rmtree(tmp)  # left by an export that was killed
    os.makedirs(os.path.dirname(tmp), exist_ok=True)
    try:
        with scheduling_kept(), h5py.File(src, "r", locking=False) as f:
            demos = _ordered_demos(f["data"])
            kept = [d for d in demos if int(f["data"][d].attrs["num_samples"]) > 0]
            if not kept:
                raise DatasetError(f"{src}: no demo has any step; nothing to export", reason="EMPTY_DATASET")
            cols = plan_columns(f, kept)
            ds = LeRobotDataset.create(repo_id=repo_id, fps=fps, features={c.feature: c.spec() for c in cols},
                                       root=tmp, robot_type=ROBOT_TYPE, use_videos=True,
                                       **({"vcodec": vcodec} if vcodec else {}))
            episodes = []
            for name in tqdm(kept, desc="lerobot export", unit="demo", disable=not progress):
                with warnings.catch_warnings():  # lerobot's stats histogram says it reads bools as uint8
                    warnings.filterwarnings("ignore", "Converting input from bool", RuntimeWarning)
                    _write_episode(ds, f["data"][name], cols, task)
                episodes.append({"episode_index": len(episodes), "demo": name, **_demo_attrs(f["data"][name])})
            ds.finalize()
        with open(os.path.join(tmp, META_FILE), "w") as fh:
            json.dump({"source": os.path.abspath(src), "env_args": env_args, "episodes": episodes}, fh, indent=1)
        os.replace(tmp, dst)  # an empty directory at dst is replaced
    except BaseException as e:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(e, (DatasetError, KeyboardInterrupt, SystemExit)):
            raise
        raise DatasetError(f"exporting {src} to LeRobot failed, nothing written: {type(e).__name__}: {e}",
                           reason="EXPORT_FAILED") from e
    return LeRobotSummary(str(dst), len(episodes), int(ds.meta.total_frames), fps, tuple(c.feature for c in cols),
                          tuple(ds.meta.video_keys), codebase_version(), tuple(sorted(set(demos) - set(kept))))


def _write_episode(ds, g, cols: list[Column], task: str) -> None:
    arrays = _episode_arrays(g, cols)
    for t in range(int(g.attrs["num_samples"])):
        ds.add_frame({**{k: v[t] for k, v in arrays.items()}, "task": task})
    # lerobot#3343: add_frame wants (1,)-shaped features as (1,) arrays, but datasets stores them as
    # scalars and numpy >= 2.4 no longer converts a (1,) array to one: hand them over as 0-d arrays.
    for c in cols:
        if c.shape == (1,) and c.dtype != "video":
            ds.episode_buffer[c.feature] = [np.reshape(v, ()) for v in ds.episode_buffer[c.feature]]
    ds.save_episode(parallel_encoding=False)


def _demo_attrs(g) -> dict:
    """The demo's attributes (success, reason, index, source_demos, ...), JSON-ready."""
    return {k: _attr_value(v) for k, v in g.attrs.items()}

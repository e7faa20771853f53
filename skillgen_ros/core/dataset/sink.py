"""Where attempts go: successes into the dataset, failures (with their reason) into a second file."""
from __future__ import annotations

import os
from collections import Counter

from ..generation.attempt import AttemptResult, GenerationConfig
from ..generation.mimicgen import spec_record
from .hdf5 import DatasetError, DatasetWriter

DATASET_FILE = "demo.hdf5"
FAILED_FILE = "failed.hdf5"


def make_env_args(task: str, variant: str, method: str, seed: int, config: GenerationConfig,
                  object_ids=(), source_demos=()) -> dict:
    """robomimic's env_args: env_name/type/env_kwargs, plus what regenerates the run (with the
    absolute paths of the source-demo bags it was generated from, `generation.source_demos`)."""
    return {
        "env_name": task, "type": "skillgen_ros",
        "env_kwargs": {"variant": variant, "control_freq": 20, "controller": "OSC_POSE",
                       "max_dpos": config.scale.max_dpos, "max_drot": config.scale.max_drot,
                       "object_ids": list(object_ids)},
        "generation": {"method": method, "seed": int(seed), "action_noise": config.action_noise,
                       "selection": config.selection, "augment": config.augment,
                       "augment_translation": config.augmentation.translation,
                       "augment_rotation_deg": config.augmentation.rotation_deg,
                       "interpolation_steps": config.interpolation_steps, "fixed_steps": config.fixed_steps,
                       "initiation_candidates": config.initiation_candidates,
                       "observation_source": config.observation_source,
                       "profile": config.profile, "release_moves": config.release.unjam_max > 0
                       or config.release.follow > 0 or config.release.clear_max > 0,
                       "planner_extras": config.planner_extras, "check_collisions": config.check_collisions,
                       "source_demos": [os.path.abspath(str(p)) for p in source_demos],
                       **({"mimicgen": spec_record(task)} if method == "mimicgen" else {})},
    }


def attempt_attrs(r: AttemptResult) -> dict:
    return {"method": r.method, "index": r.index, "scene_seed": r.scene_seed, "source_demos": list(r.source_demos),
            "success": r.success, "reason": r.reason.value, "message": r.message,
            "timings": {k: round(v, 6) for k, v in r.timings.items()},
            "initiation_candidates_used": list(r.initiation_candidates_used)}


class AttemptSink:
    """Routes each AttemptResult to demo.hdf5 or failed.hdf5 under `out_dir` and counts reasons."""

    def __init__(self, out_dir: str, env_args: dict, mode: str = "create", keep_timings: bool = True):
        self.dataset_path = os.path.join(out_dir, DATASET_FILE)
        self.failed_path = os.path.join(out_dir, FAILED_FILE)
        self.keep_timings = keep_timings  # False makes files byte-identical across runs
        if mode == "create":  # check both before creating either, so a refused run leaves no new file
            for p in (self.dataset_path, self.failed_path):
                if os.path.exists(p):
                    raise DatasetError(f"{p} exists; choose another output directory or overwrite",
                                       reason="OUTPUT_EXISTS")
        self._ok = DatasetWriter(self.dataset_path, env_args, mode)
        self._failed = DatasetWriter(self.failed_path, env_args, mode, allow_empty=True)
        self.counts: Counter = Counter()

    def add(self, r: AttemptResult) -> str:
        """Store the attempt; returns its demo name in whichever file it went to."""
        self.counts[r.reason.value] += 1
        attrs = attempt_attrs(r)
        if not self.keep_timings:
            attrs.pop("timings")
        if r.success:
            keys = ["successful"] + ([f"source_{r.source_demos[0]}"] if len(set(r.source_demos)) == 1 else [])
            return self._ok.append(r.episode, attrs, keys)
        return self._failed.append(r.episode, attrs, [r.reason.value])

    def close(self) -> None:
        self._ok.close()
        self._failed.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

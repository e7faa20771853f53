"""`skillgen dataset`: check, merge and export generated datasets.

    skillgen dataset validate out/run/demo.hdf5
    skillgen dataset merge out/shard0/demo.hdf5 out/shard1/demo.hdf5 -o out/all/demo.hdf5
    skillgen dataset export out/run/demo.hdf5 --format robomimic-next-obs -o out/run/demo_next_obs.hdf5
    skillgen dataset export out/run/demo.hdf5 --format lerobot -o out/run/lerobot

Shards come from runs over disjoint attempt indices (`skillgen generate --first-index K
--attempts N` with one seed); attempts depend only on (seed, index), so the merge equals one run.
`export --format robomimic-next-obs` writes a copy with next_obs/ in every demo, which
robomimic's offline-RL algorithms (BCQ, CQL, IQL; SequenceDataset(load_next_obs=True)) read
(core/dataset/next_obs.py, docs/dataset.md). `export --format lerobot` writes a LeRobotDataset
(parquet + videos + meta/, written by lerobot's own writer) keeping the HSP labels as features
(core/dataset/lerobot_export.py; needs the optional lerobot extra).
"""
from __future__ import annotations

import argparse
import json
import os

from skillgen_ros.core.dataset.hdf5 import DatasetError, merge_datasets, validate_dataset

EXPORT_FORMATS = {
    "robomimic-next-obs": "add next_obs/ for robomimic's offline RL (BCQ, CQL, IQL); -o is a file",
    "lerobot": "a LeRobotDataset (parquet + videos + meta/) with the HSP labels as features; -o is a "
               "directory (absent or empty); needs the lerobot extra",
}


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="skillgen dataset", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    v = sub.add_parser("validate", help="check a file against the documented layout")
    v.add_argument("path", help="a demo.hdf5 or failed.hdf5")
    m = sub.add_parser("merge", help="merge shards, ordered by attempt index")
    m.add_argument("inputs", nargs="+", help="the shards' demo.hdf5 files")
    m.add_argument("-o", "--output", required=True, help="the merged file (must not exist)")
    e = sub.add_parser("export", help="write a copy in another layout")
    e.add_argument("path", help="a demo.hdf5")
    e.add_argument("--format", required=True, metavar="FORMAT",
                   help="; ".join(f"{k}: {v}" for k, v in EXPORT_FORMATS.items()))
    e.add_argument("-o", "--output", required=True, help="the exported file or directory (must not exist)")
    e.add_argument("--repo-id", default=None,
                   help="lerobot: the dataset's repo_id in meta/ (default skillgen_ros/<task>_<variant>)")
    return p


def _export(a) -> dict:
    if a.format not in EXPORT_FORMATS:
        raise DatasetError(f"unknown export format {a.format!r}; one of {', '.join(EXPORT_FORMATS)}",
                           reason="UNKNOWN_FORMAT")
    if a.format == "lerobot":
        # The export is local: nothing may contact the Hugging Face hub. Our bar over the demos
        # replaces datasets' per-episode bars; SVT-AV1 prints only errors.
        os.environ.setdefault("HF_HUB_OFFLINE", "1")
        os.environ.setdefault("HF_DATASETS_DISABLE_PROGRESS_BARS", "1")
        os.environ.setdefault("SVT_LOG", "1")
        from skillgen_ros.core.dataset.lerobot_export import export_lerobot

        r = export_lerobot(a.path, a.output, repo_id=a.repo_id, progress=True)
        return {"path": r.path, "episodes": r.episodes, "frames": r.frames, "fps": r.fps,
                "codebase_version": r.codebase_version, "features": list(r.features),
                "videos": list(r.video_keys), "skipped_empty_demos": list(r.skipped_empty)}
    from skillgen_ros.core.dataset.next_obs import add_next_obs

    s = add_next_obs(a.path, a.output)
    return {"path": s.path, "demos": s.num_demos, "samples": s.total, "filter_keys": s.filter_keys}


def main(argv: list[str]) -> int:
    a = _parser().parse_args(argv)
    if a.cmd == "validate":
        s = validate_dataset(a.path)
    elif a.cmd == "merge":
        s = merge_datasets(a.inputs, a.output)
    else:
        print(json.dumps(_export(a), indent=2))
        return 0
    print(json.dumps({"path": s.path, "demos": s.num_demos, "samples": s.total, "filter_keys": s.filter_keys},
                     indent=2))
    return 0

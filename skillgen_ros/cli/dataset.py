"""`skillgen dataset`: check, merge and export generated datasets.

    skillgen dataset validate out/run/demo.hdf5
    skillgen dataset merge out/shard0/demo.hdf5 out/shard1/demo.hdf5 -o out/all/demo.hdf5
    skillgen dataset export out/run/demo.hdf5 --format robomimic-next-obs -o out/run/demo_next_obs.hdf5

Shards come from runs over disjoint attempt indices (`skillgen generate --first-index K
--attempts N` with one seed); attempts depend only on (seed, index), so the merge equals one run.
`export --format robomimic-next-obs` writes a copy with next_obs/ in every demo, which
robomimic's offline-RL algorithms (BCQ, CQL, IQL; SequenceDataset(load_next_obs=True)) read
(core/dataset/next_obs.py, docs/dataset.md).
"""
from __future__ import annotations

import argparse
import json

from skillgen_ros.core.dataset.hdf5 import merge_datasets, validate_dataset

EXPORT_FORMATS = ("robomimic-next-obs",)


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
    e.add_argument("--format", required=True, choices=EXPORT_FORMATS,
                   help="robomimic-next-obs: add next_obs/ for robomimic's offline RL (BCQ, CQL, IQL)")
    e.add_argument("-o", "--output", required=True, help="the exported file (must not exist)")
    return p


def main(argv: list[str]) -> int:
    a = _parser().parse_args(argv)
    if a.cmd == "validate":
        s = validate_dataset(a.path)
    elif a.cmd == "merge":
        s = merge_datasets(a.inputs, a.output)
    else:
        from skillgen_ros.core.dataset.next_obs import add_next_obs

        s = add_next_obs(a.path, a.output)
    print(json.dumps({"path": s.path, "demos": s.num_demos, "samples": s.total, "filter_keys": s.filter_keys},
                     indent=2))
    return 0

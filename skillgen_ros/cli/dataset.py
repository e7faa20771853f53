"""`skillgen dataset`: check and merge generated datasets.

    skillgen dataset validate out/run/demo.hdf5
    skillgen dataset merge out/shard0/demo.hdf5 out/shard1/demo.hdf5 -o out/all/demo.hdf5

Shards come from runs over disjoint attempt indices (`skillgen generate --first-index K
--attempts N` with one seed); attempts depend only on (seed, index), so the merge equals one run.
"""
from __future__ import annotations

import argparse
import json

from skillgen_ros.core.dataset.hdf5 import merge_datasets, validate_dataset


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="skillgen dataset")
    sub = p.add_subparsers(dest="cmd", required=True)
    v = sub.add_parser("validate", help="check a file against the documented layout")
    v.add_argument("path")
    m = sub.add_parser("merge", help="merge shards, ordered by attempt index")
    m.add_argument("inputs", nargs="+")
    m.add_argument("-o", "--output", required=True)
    a = p.parse_args(argv)
    s = validate_dataset(a.path) if a.cmd == "validate" else merge_datasets(a.inputs, a.output)
    print(json.dumps({"path": s.path, "demos": s.num_demos, "samples": s.total, "filter_keys": s.filter_keys},
                     indent=2))
    return 0

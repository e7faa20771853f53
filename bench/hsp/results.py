"""bench/hsp/results: the benchmark's cells, methods and the paper's numbers, and the results JSON they fill.

One place for what run.py writes and device.py, table.py and gen_workers.py read: the file is rewritten
atomically after every unit of work, a cell's table is each method's best evaluation, and the summary
averages the cells done. Another process's records of the same protocol can be merged in.
"""
from __future__ import annotations

import json
import os
import shlex
import sys
from pathlib import Path

from bench.machine import machine_info

CELLS = ("Square/D0", "Square/D1", "Square/D2", "Threading/D0", "Threading/D1", "NutAssembly/D0", "NutAssembly/D1")
METHODS = ("HSP-TAMP", "HSP-Class", "HSP-Reg", "MimicGen-BC")
MODE = {"HSP-TAMP": "tamp", "HSP-Class": "class", "HSP-Reg": "reg", "MimicGen-BC": "bc"}
NETWORK = {"HSP-TAMP": "hsp", "HSP-Class": "hsp", "HSP-Reg": "hsp", "MimicGen-BC": "bc"}
# The paper's success rates for these cells (Fig. 5 table, as issue 23 quotes it), percent.
PAPER = {
    "Square/D0": {"MimicGen-BC": 90.7, "HSP-TAMP": 100, "HSP-Class": 100, "HSP-Reg": 94},
    "Square/D1": {"MimicGen-BC": 73.3, "HSP-TAMP": 100, "HSP-Class": 98, "HSP-Reg": 62},
    "Square/D2": {"MimicGen-BC": 49.3, "HSP-TAMP": 94, "HSP-Class": 94, "HSP-Reg": 52},
    "Threading/D0": {"MimicGen-BC": 98, "HSP-TAMP": 100, "HSP-Class": 92, "HSP-Reg": 94},
    "Threading/D1": {"MimicGen-BC": 60.7, "HSP-TAMP": 72, "HSP-Class": 66, "HSP-Reg": 60},
    "NutAssembly/D0": {"MimicGen-BC": 60, "HSP-TAMP": 100, "HSP-Class": 92, "HSP-Reg": 94},
    "NutAssembly/D1": {"MimicGen-BC": 16, "HSP-TAMP": 72, "HSP-Class": 78, "HSP-Reg": 20},
}


class Store:
    """The results JSON, rewritten atomically after every unit of work."""

    def __init__(self, path: Path, args):
        self.path = path
        self.data = json.loads(path.read_text()) if path.exists() else {}
        if args.reevaluate and self.data.get("protocol"):  # the training run's protocol and machine stay
            self.data.setdefault("reevaluations", []).append(
                {"reason": args.reevaluate, "cells": args.cells, "methods": args.methods, "machine": machine_info(),
                 "command": shlex.join([".venv/bin/python", "bench/hsp/run.py", *sys.argv[1:]])})
        else:
            self.data["machine"] = machine_info()
            self.data["protocol"] = {k: v for k, v in vars(args).items() if k not in ("cells", "methods", "reevaluate",
                                                                                  "datasets_from", "gen_workers",
                                                                                  "eval_workers")}
            from skillgen_ros.core.learning.observation import LOW_DIM_KEYS
            self.data["protocol"]["low_dim_keys"] = list(LOW_DIM_KEYS)  # what the networks read
        self.data.setdefault("cells", {})

    def cell(self, name: str) -> dict:
        return self.data["cells"].setdefault(name, {"datasets": {}, "networks": {}, "methods": {}})

    def save(self) -> None:
        write_json(self.path, self.data)


def write_json(path: Path, data: dict) -> None:
    """Atomically: an interrupted write leaves the previous results."""
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2))
    os.replace(tmp, path)


def update_table(c: dict, methods) -> None:
    """A cell's table: the best evaluation of each of `methods` that has one."""
    c["table"] = {m: c["methods"][m]["best"] for m in methods if "best" in c["methods"].get(m, {})}


def best_rates(data: dict) -> dict[str, dict[str, float]]:
    """{method: {cell: best success rate}} over the cells where the method has an evaluation."""
    return {m: {n: c["methods"][m]["best"]["success_rate"] for n, c in data.get("cells", {}).items()
                if "best" in c.get("methods", {}).get(m, {})} for m in METHODS}


# the goal measure: HSP-Class minus MimicGen BC on the D1/D2 cells (>= 20 points)
GOAL_PAIR = ("HSP-Class", "MimicGen-BC")


def goal_cell(name: str) -> bool:
    """A cell the goal measure averages over: a D1 or D2 variant."""
    return name.split("/")[1] in ("D1", "D2")


def paper_class_minus_bc(cells) -> float:
    """The paper's HSP-Class minus MimicGen BC, mean over `cells`, in points."""
    return sum(PAPER[n][GOAL_PAIR[0]] - PAPER[n][GOAL_PAIR[1]] for n in cells) / len(cells)


def class_minus_bc(data: dict) -> tuple[list[str], float | None]:
    """The issue's goal measure: the D1/D2 cells with both HSP-Class and MimicGen BC, and the mean of
    HSP-Class minus BC over them in points (None without such a cell)."""
    cells = data.get("cells", {})
    pair = GOAL_PAIR
    hard = [n for n, c in cells.items() if goal_cell(n)
            and all("best" in c.get("methods", {}).get(m, {}) for m in pair)]
    rate = {m: {n: cells[n]["methods"][m]["best"]["success_rate"] for n in hard} for m in pair}
    gap = (100 * sum(rate[pair[0]][n] - rate[pair[1]][n] for n in hard) / len(hard)) if hard else None
    return hard, gap


def summary(data: dict) -> dict:
    """Per-method averages over the cells done, and HSP-Class minus BC on the D1/D2 cells."""
    avg = {m: 100 * sum(v.values()) / len(v) for m, v in best_rates(data).items() if v}
    return {"average_percent": avg, "hsp_class_minus_bc_d1_d2_points": class_minus_bc(data)[1],
            "cells_done": sorted(data["cells"])}


def merge_from(src: Path, dst: Path, a) -> int:
    """Another process's records of the same protocol (the same command but --methods, --out, --threads)."""
    other, mine = json.loads(src.read_text()), json.loads(dst.read_text())
    skip = ("out", "threads", "merge_from")
    differ = {k for k in set(other["protocol"]) | set(mine["protocol"]) if k not in skip
              and other["protocol"].get(k) != mine["protocol"].get(k)}
    if differ:
        raise SystemExit(f"{src} ran another protocol ({sorted(differ)}); not merged")
    for cell in a.cells:
        o, c = other["cells"][cell], mine["cells"].setdefault(cell, {"datasets": {}, "networks": {}, "methods": {}})
        for k in ("rerun", "paper"):  # a cell new to dst: its rerun command and the paper's numbers, too
            c.setdefault(k, o.get(k))
        for m in a.methods:
            net = NETWORK[m]
            c["methods"][m] = {**o["methods"][m], "merged_from": str(src.name)}
            c["datasets"][net], c["networks"][net] = o["datasets"][net], o["networks"][net]
        update_table(c, METHODS)
    mine["summary"] = summary(mine)
    write_json(dst, mine)
    print(f"merged {a.methods} of {a.cells} from {src} into {dst}")
    return 0

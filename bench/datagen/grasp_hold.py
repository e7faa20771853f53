"""bench/datagen/grasp_hold.py: what our demonstrator's pause between closing and lifting did to MimicGen.

Until 2026-12-06 the human-like demonstrator held the hand 0.6-0.78 s after closing on an object and eased the lift
in (min-jerk): the first cm came 23-28 control steps after the close. MimicGen ends a grasp subtask at its grasp
signal plus 5-10 steps (10-20 for Square and Nut Assembly; generate_core_configs.py), so its next subtask began with
the source hand still at the table, and replayed in the next object's frame it dragged the held object across the
table (docs/tasks.md). The shipped demos now lift as soon as the fingers have stopped (core/demonstrator/human_like.py
`PROMPT_LIFT`; first cm 8-10 steps after the close). This makes ten demos per task in the old style in
out/demos/grasp_hold/<task> and runs the same attempts (seed, profile, action noise) from them and from the shipped
bags, per method: how many succeed and how far the carried objects slid. The old-style demos are the earlier shipped
bags' trajectories (the same arrays; the files differ by subsets.yaml's contact_model line). An experiment on our
source demos, not a baseline; the baseline cells are bench/datagen/run.py's.

    .venv/bin/python bench/datagen/grasp_hold.py [--cells ThreePieceAssembly/D0 Coffee/D0] [--methods mimicgen skillgen]
        [--attempts 40] [--seed 1000]

Writes bench/results/grasp_hold.json (cells of an earlier run with the same settings are kept).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.datagen.demo_style import add_settings, kept_cells, make_demos, paired_row, settings  # noqa: E402
from bench.machine import machine_info  # noqa: E402

OUT = ROOT / "bench" / "results" / "grasp_hold.json"
OLD = ROOT / "out" / "demos" / "grasp_hold"
ARMS = ("hold, then eased lift (the demos shipped until 2026-12-06)", "prompt lift (shipped since 2026-12-06)")
KEEP = ("successes", "rate", "failures", "drag_m", "attempts_dragging", "successes_dragging",
        "joint_at_limit_in_a_skill", "wall_seconds", "source_demos")


def make_old_demos(task: str, force: bool) -> Path:
    """Ten demos of `task` from the demonstrator with PROMPT_LIFT off (made once, or again with --force)."""
    return make_demos(task, OLD, force, PROMPT_LIFT=False)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", nargs="+", default=["ThreePieceAssembly/D0", "Coffee/D0", "Square/D1", "Threading/D0"],
                    help="TASK/VARIANT")
    ap.add_argument("--methods", nargs="+", default=["mimicgen", "skillgen"], choices=["mimicgen", "skillgen"])
    add_settings(ap)
    a = ap.parse_args(argv)
    t0 = time.time()
    out = {"experiment": __doc__.splitlines()[0].split(": ", 1)[1], "machine": machine_info(), **settings(a),
           "arms": list(ARMS), "cells": kept_cells(OUT, a)}
    for cell in a.cells:
        task = cell.split("/")[0]
        arms = {ARMS[0]: make_old_demos(task, a.force_demos), ARMS[1]: ROOT / "bags" / task}
        for method in a.methods:
            out["cells"][f"{cell} {method}"] = paired_row(cell, method, arms, a, KEEP)
    out["command"] = (f".venv/bin/python bench/datagen/grasp_hold.py --cells {' '.join(a.cells)} --methods "
                      f"{' '.join(a.methods)} --attempts {a.attempts} --seed {a.seed}")
    out["wall_seconds"] = time.time() - t0
    OUT.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""bench/datagen/release_hold.py: what our demonstrator's pause between opening and retreating does to MimicGen.

The human-like demonstrator opens on a placed object, holds 0.5-0.65 s and eases its retreat in (min-jerk): the
first cm up comes 16-22 control steps after the open. MimicGen ends a place subtask at its signal (robosuite's
checks: Three Piece's `first_piece_assembled`, true once no finger touches piece 1, and Nut Assembly's
`objects_on_pegs`, once the EE is 4.2 cm from the nut) plus 5-10 steps (10-20 for Nut Assembly; generate_core_configs.py), so its next subtask begins with the
source hand still down at the placed object, and the 5-step interpolation to that subtask's first target, in the
next object's frame, sweeps the open fingers through it (Three Piece D0: piece 1 knocked off the base in 12 of 40
attempts; bench/datagen/diagnose.py --stages). `PROMPT_RETREAT` (core/demonstrator/human_like.py) rises as soon
as the fingers are off. This makes ten demos per task in the style the shipped bags are not in
(out/demos/release_hold/<task>) and runs the same attempts (seed, profile, action noise) from both, per method:
successes and, for Three Piece, how far each failed attempt got. An experiment on our source demos, not a
baseline; the baseline cells are bench/datagen/run.py's.

    .venv/bin/python bench/datagen/release_hold.py [--cells ThreePieceAssembly/D0 NutAssembly/D0]
        [--methods mimicgen skillgen] [--attempts 40] [--seed 1000]

Writes bench/results/release_hold.json (cells of an earlier run with the same settings are kept).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.datagen.attempt_tally import STAGES  # noqa: E402
from bench.datagen.demo_style import add_settings, kept_cells, make_demos, paired_row, settings  # noqa: E402
from bench.machine import machine_info  # noqa: E402

OUT = ROOT / "bench" / "results" / "release_hold.json"
OTHER = ROOT / "out" / "demos" / "release_hold"
ARMS = {False: "hold, then eased retreat", True: "prompt retreat"}  # PROMPT_RETREAT -> arm
KEEP = ("successes", "rate", "failures", "task_failed_stages", "slip_in_hand_m", "attempts_slipping",
        "successes_slipping", "joint_at_limit_in_a_skill", "wall_seconds", "source_demos")


def arm_bags(task: str, force: bool) -> dict[str, Path]:
    """Each arm's source demos: the shipped bags for the shipped style, ten made in OTHER for the other."""
    from skillgen_ros.core.demonstrator import ScriptedDemonstrator

    shipped = bool(ScriptedDemonstrator.PROMPT_RETREAT)
    return {f"{ARMS[shipped]} (shipped)": ROOT / "bags" / task,
            ARMS[not shipped]: make_demos(task, OTHER, force, PROMPT_RETREAT=not shipped)}


def _command(cell: str, method: str, a) -> str:
    return (f".venv/bin/python bench/datagen/release_hold.py --cells {cell} --methods {method} --attempts "
            f"{a.attempts} --seed {a.seed} --noise {a.noise} --profile {a.profile}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", nargs="+", default=["ThreePieceAssembly/D0", "NutAssembly/D0"], help="TASK/VARIANT")
    ap.add_argument("--methods", nargs="+", default=["mimicgen", "skillgen"], choices=["mimicgen", "skillgen"])
    add_settings(ap)
    a = ap.parse_args(argv)
    t0 = time.time()
    out = {"experiment": __doc__.splitlines()[0].split(": ", 1)[1], "machine": machine_info(), **settings(a),
           "arms": list(ARMS.values()), "cells": kept_cells(OUT, a)}
    for cell in a.cells:
        task = cell.split("/")[0]
        try:
            arms = arm_bags(task, a.force_demos)
        except SystemExit as e:  # the demonstrator failed a scene in the other style: say so, go on
            for method in a.methods:
                out["cells"][f"{cell} {method}"] = {"error": str(e), "command": _command(cell, method, a)}
            print(f"{cell}: {e}", flush=True)
            continue
        for method in a.methods:
            out["cells"][f"{cell} {method}"] = {"command": _command(cell, method, a),
                                                **paired_row(cell, method, arms, a, KEEP, stages=task in STAGES)}
            OUT.write_text(json.dumps(out, indent=1) + "\n")  # each cell as it finishes
    out["wall_seconds"] = time.time() - t0
    OUT.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""What bench/datagen's demo-style experiments share (coffee_lid_push.py, grasp_hold.py, release_hold.py): ten demos
made with the demonstrator in another style, the settings that decide whether an earlier run's results can be kept,
and (the per-cell experiments) the kept cells and one cell's row of arms."""
from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path


def make_demos(task: str, out: Path, force: bool, **style) -> Path:
    """Ten demos of `task` in out/<task> with ScriptedDemonstrator's class attributes `style` set for the run (made
    once, or again with `force`); the attributes are restored after."""
    from skillgen_ros.cli.main import main as cli
    from skillgen_ros.core.demonstrator import ScriptedDemonstrator

    bags = out / task
    if force or not bags.exists():
        before = {k: getattr(ScriptedDemonstrator, k) for k in style}
        for k, v in style.items():
            setattr(ScriptedDemonstrator, k, v)
        try:
            if cli(["demos", "make", "--task", task, "--out", str(out), "--force"]) != 0:
                shutil.rmtree(bags, ignore_errors=True)  # a partial set must not pass for the demos next time
                raise SystemExit(f"could not make the {task} demos with {style}")
        finally:
            for k, v in before.items():
                setattr(ScriptedDemonstrator, k, v)
    return bags


def add_settings(ap: argparse.ArgumentParser) -> None:
    """The attempts' settings, shared by both arms of an experiment."""
    ap.add_argument("--attempts", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--noise", type=float, default=0.05)
    ap.add_argument("--profile", default="paper")
    ap.add_argument("--force-demos", action="store_true", help="remake the other style's demos")


def settings(a: argparse.Namespace) -> dict:
    """The run's settings under the JSON's keys."""
    return {"seed": a.seed, "attempts": a.attempts, "profile": a.profile, "action_noise": a.noise}


def same_settings(old: dict, a: argparse.Namespace) -> bool:
    """Whether an earlier JSON was measured with this run's settings (only then are its results kept)."""
    return all(old.get(k) == v for k, v in settings(a).items())


def kept_cells(out: Path, a: argparse.Namespace) -> dict:
    """The "TASK/VARIANT method" cells of the results file `out` measured with the same settings that this run
    (a.cells x a.methods) does not redo."""
    old = json.loads(out.read_text()) if out.exists() else {}
    if not same_settings(old, a):
        return {}
    redone = {f"{cell} {m}" for cell in a.cells for m in a.methods}
    return {c: r for c, r in old.get("cells", {}).items() if c not in redone}


def paired_row(cell: str, method: str, arms: dict, a: argparse.Namespace, keep, **diagnose_kw) -> dict:
    """One "TASK/VARIANT" cell and method: the same attempts (a's settings) from each arm's source demos
    (arm -> bags folder), `keep`'s keys of each diagnose entry."""
    from bench.datagen.diagnose import diagnose

    task, variant = cell.split("/")
    row = {}
    for arm, bags in arms.items():
        e = diagnose(task, variant, a.attempts, a.noise, a.seed, a.profile, method=method, bags=bags, **diagnose_kw)
        row[arm] = {k: e[k] for k in keep if k in e}
        print(f"{cell} {method} {arm}: {e['successes']}/{a.attempts} {e.get('task_failed_stages', '')}".rstrip(),
              flush=True)
    return row

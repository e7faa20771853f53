"""The source demos a datagen cell ran from, by content.

A cell's number reruns only from the demos it was measured on. Each cell records the sha256 of its task's
source demo folder (bags/<task>, or out/demos/<model>/<task> on another contact model); bench/readme_table.py
marks a cell whose folder has been remade since, so a remade task's old numbers cannot pass for current ones.
"""
from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def digest(demo_dir: Path) -> str:
    """sha256 over every file under demo_dir: its path relative to demo_dir, then its bytes, in path order."""
    demo_dir = Path(demo_dir)
    if not demo_dir.is_dir():
        raise FileNotFoundError(f"{demo_dir}: no source demos there")
    h = hashlib.sha256()
    for p in sorted(q for q in demo_dir.rglob("*") if q.is_file()):
        h.update(p.relative_to(demo_dir).as_posix().encode() + b"\0")
        h.update(p.read_bytes())
    return h.hexdigest()


def record(demo_dir: Path) -> dict:
    """What a cell stores: the folder (relative to the repository where it is inside it) and its digest."""
    demo_dir = Path(demo_dir).resolve()
    where = demo_dir.relative_to(ROOT).as_posix() if demo_dir.is_relative_to(ROOT) else str(demo_dir)
    return {"dir": where, "sha256": digest(demo_dir)}


def is_stale(cell: dict) -> bool | None:
    """True when the cell's demos were remade since it ran, False when they are the same, None when it cannot
    be told (a cell from before digests were recorded, or demos not on this machine, e.g. another model's)."""
    rec = cell.get("source_demos")
    if not rec:
        return None
    d = Path(rec["dir"]) if Path(rec["dir"]).is_absolute() else ROOT / rec["dir"]
    if not d.is_dir():
        return None
    return _current(str(d.resolve())) != rec["sha256"]


@lru_cache(maxsize=None)
def _current(demo_dir: str) -> str:
    """One digest per folder per process: a table checks a hundred cells against a few folders."""
    return digest(Path(demo_dir))

"""The paper's data-generation success rates (%), Tables "core_datagen" and "clutter_sim".

Keys are (task, variant) with the project's lower-snake task names; methods are "mimicgen",
"skillgen" and "skillgen_ia" (SkillGen with initiation augmentation). The project's single
"clutter" variant is the D1 reset regions plus the obstacle (core/tasks/suite.py), so it compares
against the paper's clutter row built on D1 (Square: 62.5%, not the D2-clutter row's 72.0%); a
task without such a row compares against the mean of its clutter rows.
"""
from __future__ import annotations

_CORE = {
    "square": [(73.7, 99.8, 30.7), (48.9, 91.5, 34.3), (31.8, 87.7, 27.5)],
    "threading": [(51.0, 76.2, 35.0), (39.2, 66.4, 27.2), (21.6, 74.3, 24.9)],
    "three_piece_assembly": [(35.6, 82.5, 5.1), (35.5, 72.7, 4.7), (31.3, 69.3, 4.6)],
    "coffee": [(78.2, 73.3, 9.3), (63.5, 73.6, 9.1), (27.7, 70.0, 8.5)],
    "nut_assembly": [(53.0, 98.6, 15.2), (30.0, 91.7, 15.1), (22.8, 69.1, 10.6)],
    "coffee_prep": [(53.2, 64.6, 1.4), (36.1, 36.8, 0.7), (0.0, 59.9, 0.6)],
}
_CLUTTER = {  # (variant the clutter was added to, mimicgen, skillgen)
    "square": [("D1", 4.0, 62.5), ("D2", 14.5, 72.0)],
    "coffee": [("D0", 16.5, 49.0), ("D1", 14.0, 55.0)],
}
CLUTTER_BASE = "D1"  # the variant whose regions the project's clutter variants use
AVERAGE = {"mimicgen": 40.7, "skillgen": 75.4, "skillgen_ia": 14.7}

PAPER_RATES: dict[tuple[str, str], dict[str, float]] = {}
for _task, _rows in _CORE.items():
    for _i, (_mg, _sg, _ia) in enumerate(_rows):
        PAPER_RATES[(_task, f"D{_i}")] = {"mimicgen": _mg, "skillgen": _sg, "skillgen_ia": _ia}
for _task, _rows in _CLUTTER.items():
    for _v, _mg, _sg in _rows:
        PAPER_RATES[(_task, f"{_v}_clutter")] = {"mimicgen": _mg, "skillgen": _sg}
    _base = [r for r in _rows if r[0] == CLUTTER_BASE]
    _rows = _base or _rows
    PAPER_RATES[(_task, "clutter")] = {"mimicgen": round(sum(r[1] for r in _rows) / len(_rows), 2),
                                       "skillgen": round(sum(r[2] for r in _rows) / len(_rows), 2)}

_ALIASES = {"piece_assembly": "three_piece_assembly", "threepieceassembly": "three_piece_assembly",
            "nut": "nut_assembly", "nutassembly": "nut_assembly", "coffeepreparation": "coffee_prep"}


def method_key(method: str, augment: bool) -> str:
    return "skillgen_ia" if method == "skillgen" and augment else method


def paper_rate(task: str, variant: str, method: str, augment: bool = False) -> float | None:
    """The paper's rate in percent, or None when the paper has no such cell."""
    t = _ALIASES.get(task.lower(), task.lower())
    return PAPER_RATES.get((t, variant), {}).get(method_key(method, augment))

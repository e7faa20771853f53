"""Aggregates of bench/datagen cells that compare like with like (used by run.py and readme_table.py).

A cell is one (task, variant, method, augment, profile). Averages against the paper are taken only
over cells both sides have, each beside the paper's mean over the same cells:
- core: the paper's 18 simulation variants (Square, Threading, Nut Assembly, Three Piece Assembly, Coffee,
  Coffee Prep x D0-D2), over the cells run; with all 18 the paper's side is its own 18-variant average
  (PAPER_18_AVERAGE: 75.4 / 40.7 / 14.7).
- clutter: the paper's clutter rows (Square D1/D2 clutter), never mixed into core.
- margin: skillgen minus MimicGen over Square, Threading and Nut Assembly D1-D2 (paper: 80.1 vs
  32.4, +47.7), only when every one of those cells ran for both methods.
Cells the paper does not have (PickPlace, a clutter variant without a paper row) are listed on
their own, never averaged with the others.
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from skillgen_ros.core.dataset.paper import AVERAGE as PAPER_18_AVERAGE  # noqa: E402  (75.4 / 40.7 / 14.7)
from skillgen_ros.core.dataset.paper import paper_rate  # noqa: E402

CORE_TASKS = ("Square", "Threading", "NutAssembly", "ThreePieceAssembly", "Coffee", "CoffeePreparation")
CORE_VARIANTS = ("D0", "D1", "D2")
MARGIN_CELLS = tuple((t, v) for t in ("Square", "Threading", "NutAssembly") for v in ("D1", "D2"))  # the 80.1 vs 32.4
METHOD_KEYS = ("skillgen", "mimicgen", "skillgen+IA")
LEGACY_PROFILE = "skillgen_ros"  # cells measured before profiles existed ran today's skillgen_ros settings


def method_key(method: str, augment: bool) -> str:
    return method + ("+IA" if augment else "")


def cell_key(c: dict) -> tuple:
    return c["task"], c["variant"], method_key(c["method"], c["augment"]), c.get("profile", LEGACY_PROFILE)


PROFILE_FREE = ("mimicgen", "replay_noise")  # no planner, candidates or release: the same under every profile


def view(cells: list[dict], profile: str) -> list[dict]:
    """The cells of `profile`, plus profile-free methods' cells measured under another profile."""
    own = [c for c in cells if cell_key(c)[3] == profile]
    have = {cell_key(c)[:3] for c in own}
    extra = [dict(c, profile=profile) for c in cells if cell_key(c)[2] in PROFILE_FREE
             and cell_key(c)[3] != profile and cell_key(c)[:3] not in have]
    return own + list({cell_key(c): c for c in extra}.values())


def is_core(task: str, variant: str) -> bool:
    return task in CORE_TASKS and variant in CORE_VARIANTS


def is_clutter(variant: str) -> bool:
    return "clutter" in variant


def _paper(task: str, variant: str, key: str) -> float | None:
    return paper_rate(task, variant, key.replace("+IA", ""), key.endswith("+IA"))


def shared_mean(cells: list[dict], profile: str, key: str, pred) -> dict:
    """Ours and the paper's mean (percent) over the cells of `profile`/`key` that satisfy pred and
    that the paper has; the cell list says which."""
    rows = [c for c in cells if cell_key(c)[2:] == (key, profile) and pred(c["task"], c["variant"])
            and _paper(c["task"], c["variant"], key) is not None]
    if not rows:
        return {"cells": [], "ours": None, "paper": None}
    return {"cells": [f"{c['task']} {c['variant']}" for c in rows],
            "ours": round(100 * sum(c["rate"] for c in rows) / len(rows), 2),
            "paper": round(sum(_paper(c["task"], c["variant"], key) for c in rows) / len(rows), 2)}


def margin(cells: list[dict], profile: str) -> dict:
    """skillgen - mimicgen over MARGIN_CELLS (both must have every cell), beside the paper's."""
    by = {cell_key(c): c for c in cells}
    out = {"cells": [f"{t} {v}" for t, v in MARGIN_CELLS]}
    for key in ("skillgen", "mimicgen"):
        paper = [_paper(t, v, key) for t, v in MARGIN_CELLS]
        out[f"paper_{key}"] = round(sum(paper) / len(paper), 2)
        got = [by.get((t, v, key, profile)) for t, v in MARGIN_CELLS]
        out[key] = round(100 * sum(c["rate"] for c in got) / len(got), 2) if all(got) else None
    out["paper_margin"] = round(out["paper_skillgen"] - out["paper_mimicgen"], 2)
    out["margin"] = (round(out["skillgen"] - out["mimicgen"], 2)
                     if out["skillgen"] is not None and out["mimicgen"] is not None else None)
    return out


def cells_run(cells: list[dict], profile: str, key: str, part: str) -> int:
    """How many of a profile/method's core ("core") or clutter ("clutter") cells ran, the paper's or not."""
    pred = (lambda t, v: is_clutter(v)) if part == "clutter" else is_core
    return sum(cell_key(c)[2:] == (key, profile) and pred(c["task"], c["variant"]) for c in view(cells, profile))


def candidate_counts(cells: list[dict], profile: str, key: str) -> dict:
    """Initiation candidates used per skill reached, pooled over a profile/method's cells."""
    hist: dict[str, int] = {}
    retried = attempts = 0
    for c in cells:
        if cell_key(c)[2:] != (key, profile):
            continue
        for k, v in (c.get("initiation_candidates_used") or {}).items():
            hist[k] = hist.get(k, 0) + v
        retried += c.get("attempts_with_retry", 0)
        attempts += c["attempts"]
    return {"per_skill": dict(sorted(hist.items(), key=lambda kv: int(kv[0]))), "attempts_with_retry": retried,
            "attempts": attempts}


def summarize(cells: list[dict]) -> dict:
    profiles = sorted({cell_key(c)[3] for c in cells})
    out: dict = {"paper_18_variant_average": dict(PAPER_18_AVERAGE),
                 "note": "core/clutter: ours and the paper's mean over the same cells; the paper's 18-variant "
                         "averages are a core mean's paper side only where it covers all 18 cells"}
    everything = cells
    for prof in profiles:
        cells = view(everything, prof)
        p = out.setdefault(prof, {})
        for key in METHOD_KEYS + ("replay_noise",):
            p[key] = {"core": shared_mean(cells, prof, key, is_core),
                      "clutter": shared_mean(cells, prof, key, lambda t, v: is_clutter(v)),
                      "unpaired": [f"{c['task']} {c['variant']}: {100 * c['rate']:.1f}%" for c in cells
                                   if cell_key(c)[2:] == (key, prof) and _paper(c["task"], c["variant"], key) is None]}
            if key.startswith("skillgen"):
                p[key]["initiation_candidates"] = candidate_counts(cells, prof, key)
        p["d1_d2_margin"] = margin(cells, prof)
    return out

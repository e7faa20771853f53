"""bench/datagen/summary.py: averages against the paper only over cells both sides have."""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench.datagen.summary import MARGIN_CELLS, summarize  # noqa: E402


def _cell(task, variant, method, rate, profile="paper", augment=False, used=None):
    return {"task": task, "variant": variant, "method": method, "augment": augment, "profile": profile,
            "rate": rate, "attempts": 10, "initiation_candidates_used": used or {}, "attempts_with_retry": 0}


def test_averages_cover_shared_cells_only():
    cells = [_cell("Square", "D0", "skillgen", 1.0), _cell("PickPlace", "D0", "skillgen", 0.5),
             _cell("Square", "D1_clutter", "skillgen", 0.6), _cell("Square", "D0", "skillgen", 0.9, "skillgen_ros")]
    s = summarize(cells)
    core = s["paper"]["skillgen"]["core"]
    assert core == {"cells": ["Square D0"], "ours": 100.0, "paper": 99.8}  # PickPlace is not averaged in
    assert s["paper"]["skillgen"]["clutter"] == {"cells": ["Square D1_clutter"], "ours": 60.0, "paper": 62.5}
    assert s["paper"]["skillgen"]["unpaired"] == ["PickPlace D0: 50.0%"]
    assert s["skillgen_ros"]["skillgen"]["core"]["ours"] == 90.0  # profiles never mix
    assert s["paper_18_variant_average"] == {"mimicgen": 40.7, "skillgen": 75.4, "skillgen_ia": 14.7}
    assert s["paper"]["d1_d2_margin"]["margin"] is None  # not every D1/D2 cell ran


def test_d1_d2_margin_needs_every_cell_and_reuses_mimicgen_across_profiles():
    cells = [_cell(t, v, "skillgen", 0.9) for t, v in MARGIN_CELLS] + [_cell(t, v, "mimicgen", 0.3) for t, v in MARGIN_CELLS]
    cells += [_cell(t, v, "skillgen", 1.0, "skillgen_ros", used={"1": 5, "2": 1}) for t, v in MARGIN_CELLS]
    s = summarize(cells)
    m = s["paper"]["d1_d2_margin"]
    assert (m["skillgen"], m["mimicgen"], m["margin"]) == (90.0, 30.0, 60.0)
    assert (m["paper_skillgen"], m["paper_mimicgen"], m["paper_margin"]) == pytest.approx((80.12, 32.38, 47.74), abs=0.01)
    assert s["skillgen_ros"]["d1_d2_margin"]["margin"] == 70.0  # MimicGen has no profile: the same runs
    assert s["skillgen_ros"]["skillgen"]["initiation_candidates"]["per_skill"] == {"1": 30, "2": 6}


def test_diagnose_counts_the_plans_each_start_repair_served():
    from types import SimpleNamespace

    from bench.datagen import diagnose

    msgs = iter([("SUCCESS", "9 waypoints; start: wrist touches square_nut, square_peg (allowed on the retreat)"),
                 ("SUCCESS", "7 waypoints; start in collision: moved 0.12 rad in the null space"),
                 ("START_IN_COLLISION", "start configuration collides"), ("SUCCESS", "5 waypoints, 1.20 s")])

    def plan(*args, **kwargs):
        status, message = next(msgs)
        return SimpleNamespace(status=SimpleNamespace(name=status), message=message)

    env = SimpleNamespace(planner=SimpleNamespace(plan=plan))
    seen = diagnose._count_start_repairs(env)
    for _ in range(4):
        env.planner.plan(None, None)
    assert seen["plans"] == 4 and seen["START_IN_COLLISION"] == 1
    assert seen["wrist_backout"] == 1 and seen["null_space_escape"] == 1 and seen["hand_backout"] == 0

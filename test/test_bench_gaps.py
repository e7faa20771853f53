"""bench/datagen/gaps.py: the README lists every paper-profile cell whose paper rate is outside our interval,
with the cell's own failure codes and the cause measured for it (a cell-specific one before its task's)."""
from __future__ import annotations

import sys

from conftest import REPO

sys.path.insert(0, str(REPO))
from bench.datagen import gaps  # noqa: E402


def _cell(task="Square", variant="D1", method="skillgen", augment=False, profile="paper", rate=0.84,
          wilson=(0.78, 0.88), paper=91.5, failures=None):
    return {"task": task, "variant": variant, "method": method, "augment": augment, "profile": profile,
            "rate": rate, "wilson95": list(wilson), "paper_rate": paper,
            "failures": failures if failures is not None else {"TASK_FAILED": 25, "PLAN_FAILED": 5}}


def test_only_cells_the_paper_has_outside_the_interval_are_listed_with_their_direction():
    cells = [_cell(),  # 91.5 above 88: below the paper
             _cell(variant="D0", rate=0.9, wilson=(0.85, 0.93), paper=90.0),  # inside: not listed
             _cell(method="mimicgen", rate=0.82, wilson=(0.76, 0.87), paper=48.9),  # above the paper
             _cell(profile="skillgen_ros", rate=0.5, wilson=(0.43, 0.57)),  # our profile: not the paper's algorithm
             _cell(task="PickPlace", variant="D0", paper=None)]  # not a paper cell
    found = gaps.gaps(cells)
    assert [(g.task, g.variant, g.method, g.direction) for g in found] == [
        ("Square", "D1", "skillgen", "below"), ("Square", "D1", "mimicgen", "above")]
    assert found[0].failures == {"TASK_FAILED": 25, "PLAN_FAILED": 5}


def test_a_cells_own_cause_comes_before_its_tasks_and_an_unmeasured_one_says_so():
    assert gaps.cause("skillgen", "Threading", "D2", "below") == gaps.CAUSES[("skillgen", "Threading", "D2", "below")]
    assert gaps.cause("skillgen", "Threading", "D1", "below") == gaps.CAUSES[("skillgen", "Threading", "below")]
    assert gaps.cause("skillgen", "Threading", "D1", "above") == gaps.NOT_PLACED
    assert gaps.cause("skillgen", "NoSuchTask", "D0", "below") == gaps.NOT_PLACED


def test_cells_sharing_a_cause_make_one_row_that_keeps_each_cells_numbers():
    cells = [_cell(task="Threading", variant=v, rate=r, wilson=w, paper=p, failures={"TASK_FAILED": f})
             for v, r, w, p, f in (("D0", 0.275, (0.22, 0.34), 76.2, 145), ("D1", 0.215, (0.16, 0.28), 66.4, 157),
                                   ("D2", 0.24, (0.19, 0.30), 74.3, 139))]
    rows = [r for r in gaps.gap_rows(cells) if r.startswith("| skillgen |")]
    assert len(rows) == 2  # D0/D1 share the task's cause, D2 has its own
    assert "D0 27.5% (22-34) / 76.2%: TASK_FAILED 145; D1 21.5% (16-28) / 66.4%: TASK_FAILED 157" in rows[0]
    assert rows[1].startswith("| skillgen | Threading | below | D2 24.0% (19-30) / 74.3%: TASK_FAILED 139 |")
    assert gaps.gap_rows([_cell(rate=0.9, wilson=(0.85, 0.93), paper=90.0)]) == []

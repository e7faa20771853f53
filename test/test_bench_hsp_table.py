"""bench/hsp/table: the README's generated HSP rows say what was measured, beside what, on which data.

A retrained T is paired with the checkpoint's own T at the same step; a cell re-run on the v2 demos with the
earlier demos' cell, and a session that ended mid-run must not read as the full budget; the v2 rows name the
baseline's data and the HSP-Class minus BC gap on the D1/D2 cells that have both, beside the paper's.
"""
from __future__ import annotations

import sys

from conftest import REPO

sys.path.insert(0, str(REPO))


def test_termination_rows_pair_a_retrained_t_with_the_checkpoints_own_at_the_same_step():
    from bench.hsp.table import termination_rows

    ev = {"successes": 38, "rollouts": 50, "wilson_95": [0.63, 0.86], "skill_endings": {"0": {"termination": 50}},
          "mean_steps": 254.3}
    data = {"runs": {"Threading/D0/step13500/settled/seed0": {"checkpoint_step": 13500, "labels": "settled",
                                                              "seed": 0, "evaluations": {"HSP-Class": ev}}}}
    own = {"step": 13500, "successes": 31, "rollouts": 50, "skill_endings": {"0": {"budget": 33}}, "mean_steps": 620.8}
    base = {"cells": {"Threading/D0": {"methods": {"HSP-Class": {"evals": [{**own, "step": 9000}, own]}}}}}
    (row,) = termination_rows(data, base)
    assert "HSP-Class, T on settled labels, seed 0: 38/50 (63-86%" in row and "vs its own T 31/50" in row
    assert "621 steps" in row and "254 steps a rollout" in row
    assert "vs its own" not in termination_rows(data, {})[0] and termination_rows({}, base) == []


def test_source_demo_rows_pair_each_method_best_and_how_skill_0_ended():
    from bench.hsp.table import source_demo_rows

    def cell(wins, step, ends):
        best = {"successes": wins, "rollouts": 50, "step": step}
        return {"methods": {"HSP-Class": {"best": best, "evals": [{"step": 4500, "skill_endings": {}},
                                                                  {"step": step, "skill_endings": {"0": ends}}]}}}
    old = {"cells": {"Square/D0": cell(36, 13500, {"budget": 37, "termination": 13})}}
    new = {"cells": {"Square/D0": cell(40, 9000, {"termination": 50})}}
    old["cells"]["Square/D0"]["methods"]["HSP-TAMP"] = cell(24, 13500, {"budget": 1, "goal": 49})["methods"][
        "HSP-Class"]
    new["cells"]["Square/D0"]["methods"]["HSP-TAMP"] = cell(18, 9000, {"goal": 50})["methods"]["HSP-Class"]
    (row,) = source_demo_rows(old, new)
    assert "HSP-Class 36/50 -> 40/50" in row
    assert "skill 0 ended by T/goal 13, budget 37 -> skill 0 ended by T/goal 50, budget 0" in row
    assert ("HSP-TAMP 24/50 -> 18/50 (skill 0 ended by T/goal 49, budget 1 -> skill 0 ended by T/goal 50, "
            "budget 0)") in row
    assert source_demo_rows(old, {}) == [] and source_demo_rows({}, new) == []
    new["cells"]["Square/D0"]["networks"] = {"hsp": {"steps": 4500, "budget_steps": 13500, "finished": False,
                                                     "train_seconds": 540.0}}
    (row,) = source_demo_rows(old, new)  # a session ended mid-run: the row must not read as the full budget's
    assert "UNFINISHED: hsp 4500 of 13500 steps so far" in row and "same protocol, steps" not in row


def test_v2_rows_name_the_baselines_data_and_the_class_minus_bc_gap_on_the_d1_d2_cells_with_both():
    from bench.hsp.table import source_demo_rows

    def best(wins):
        return {"best": {"successes": wins, "rollouts": 50, "success_rate": wins / 50, "step": 13500}, "evals": []}
    old = {"cells": {"Square/D2": {"methods": {"HSP-Class": best(17), "MimicGen-BC": best(0)}}}}
    new = {"cells": {"Square/D2": {"methods": {"HSP-Class": best(13), "MimicGen-BC": best(3)},
                                   "datasets": {"bc": {"demos": 1000, "attempts": 1550}},
                                   "networks": {"bc": {"steps": 13500, "timed_steps": 9300, "train_seconds": 1350.0,
                                                       "ms_per_train_step": 145.2, "finished": True}}},
                     "Square/D0": {"methods": {"HSP-Class": best(40), "MimicGen-BC": best(45)}}}}
    rows = source_demo_rows(old, new)
    assert ("v2 data for MimicGen-BC 1000 demos from 1550 attempts, 13500 steps, the last 9300 in 22 min"
            in rows[0]) and "MimicGen-BC 0/50 -> 3/50" in rows[0]
    # D0 is not a D1/D2 cell; the paper's Square D2: HSP-Class 94 - BC 49.3
    assert rows[-1] == ("- HSP-Class minus MimicGen BC on the v2 data, D1/D2 cells with both (Square/D2): +20.0 points "
                        "(goal >= +20; the paper on the same cells +44.7).")


def test_budget_rows_count_the_budgets_own_best_and_list_each_evaluation_past_it():
    """A longer run under a new --out (resumed from the base's last.pt) holds only the evaluations past the
    budget: the best so far includes the budget's own, and the row says how many steps this record timed."""
    from bench.hsp.table import budget_rows

    def ev(step, wins):
        return {"step": step, "successes": wins, "rollouts": 50}
    base = {"cells": {"Square/D2": {"networks": {"hsp": {"steps": 13500}},
                                    "methods": {"HSP-Class": {"best": ev(13500, 13)},
                                                "HSP-TAMP": {"best": ev(13500, 9)}}}}}
    longer = {"protocol": {"budget_minutes": 0.0, "budget_steps": 40500},
              "cells": {"Square/D2": {"networks": {"hsp": {"steps": 22500, "timed_steps": 9000,
                                                           "train_seconds": 1200.0}},
                                      "methods": {"HSP-Class": {"evals": [ev(18000, 15), ev(22500, 11)]},
                                                  "HSP-TAMP": {"evals": [ev(18000, 8)]}}}}}
    (row,) = budget_rows(base, longer, "bench/results/hsp_v2_d2_3x.json")
    assert "(bench/results/hsp_v2_d2_3x.json, goal 40500 steps per network; so far hsp: 22500 steps, the last 9000 " \
           "in 20 min)" in row
    assert "HSP-TAMP 9/50 -> 9/50 (step 13500; 8 at 18k)" in row
    assert "HSP-Class 13/50 -> 15/50 (step 18000; 15 at 18k, 11 at 22.5k)" in row
    assert budget_rows(base, {}) == [] and budget_rows({}, longer) == []


def test_equal_budget_gap_compares_both_networks_only_up_to_the_step_both_reached():
    """The BC trained to 40.5k and HSP to 36k: the gap counts evaluations up to 36k only, and the budget's own."""
    from bench.hsp.table import equal_budget_gap_rows

    def ev(step, wins):
        return {"step": step, "successes": wins, "rollouts": 50}
    base = {"cells": {"Square/D2": {"methods": {"HSP-Class": {"best": ev(13500, 13)},
                                                "MimicGen-BC": {"best": ev(13200, 3)}}}}}
    longer = {"cells": {"Square/D2": {"methods": {
        "HSP-Class": {"evals": [ev(18000, 20), ev(36000, 41)]},
        "MimicGen-BC": {"evals": [ev(18000, 2), ev(36000, 5), ev(40500, 30)]}}}}}
    (row,) = equal_budget_gap_rows(base, longer, "x.json")
    assert "both networks to 36000 steps" in row
    assert "HSP-Class 41/50 (step 36000), MimicGen-BC 5/50 (step 36000): +72.0 points" in row
    assert "(at the budget +20.0; paper +44.7)" in row
    longer["cells"]["Square/D2"]["methods"]["MimicGen-BC"]["evals"] = [ev(18000, 1)]
    (row,) = equal_budget_gap_rows(base, longer, "x.json")  # BC's budget best (3 at 13.2k) still counts
    assert "MimicGen-BC 3/50 (step 13200)" in row and "HSP-Class 20/50 (step 18000)" in row
    longer["cells"]["Square/D0"] = longer["cells"].pop("Square/D2")
    assert equal_budget_gap_rows(base, longer, "x.json") == []  # D0 is not a goal cell

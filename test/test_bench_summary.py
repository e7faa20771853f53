"""bench/datagen/summary.py: averages against the paper only over cells both sides have."""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from bench.datagen.summary import MARGIN_CELLS, cells_run, summarize  # noqa: E402


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


def test_cells_run_counts_a_methods_cells_whether_or_not_the_paper_has_them():
    cells = [_cell("Square", "D1_clutter", "skillgen", 0.2, augment=True),
             _cell("PickPlace", "clutter", "skillgen", 0.5, augment=True),
             _cell("Square", "D0", "skillgen", 0.4, augment=True), _cell("Square", "D1_clutter", "skillgen", 0.6)]
    assert summarize(cells)["paper"]["skillgen+IA"]["clutter"]["ours"] is None  # no paper IA clutter number
    assert cells_run(cells, "paper", "skillgen+IA", "clutter") == 2
    assert cells_run(cells, "paper", "skillgen+IA", "core") == 1
    assert cells_run(cells, "skillgen_ros", "skillgen+IA", "clutter") == 0


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


def test_diagnose_splits_the_first_look_at_each_skills_object_by_outcome():
    from types import SimpleNamespace

    from bench.datagen import diagnose

    skills = [SimpleNamespace(index=0, object_id="nut"), SimpleNamespace(index=1, object_id="peg")]
    rows = [(True, [(0, {"nut": (2.0, 1.0), "peg": (9.0, 9.0)}), (0, {"nut": (7.0, 7.0)}), (1, {"peg": (1.0, 0.5)})]),
            (True, [(0, {"nut": (4.0, 3.0)}), (1, {"peg": (0.5, 0.1)})]),
            (False, [(0, {"nut": (30.0, 45.0)})])]
    s = diagnose._look_summary(rows, skills)
    assert s["succeeded"]["skill 0 nut"] == {"attempts": 2, "trans_mm_median": 3.0, "trans_mm_max": 4.0,
                                             "rot_deg_median": 2.0, "rot_deg_max": 3.0}  # first looks: (2, 1), (4, 3)
    assert s["succeeded"]["skill 1 peg"]["trans_mm_max"] == 1.0  # the skill-0 look at the peg is not its own
    assert s["failed"] == {"skill 0 nut": {"attempts": 1, "trans_mm_median": 30.0, "trans_mm_max": 30.0,
                                           "rot_deg_median": 45.0, "rot_deg_max": 45.0}}


def test_diagnose_records_each_looks_errors_for_its_skill_without_the_held_object():
    from types import SimpleNamespace

    import numpy as np

    from bench.datagen import diagnose
    from skillgen_ros.core.geometry import Pose

    turned = Pose([0.5, 0.01, 0.9], [0.0, 0.0, np.sin(np.radians(45) / 2), np.cos(np.radians(45) / 2)])
    truth = {"nut": Pose([0.5, 0.0, 0.9], [0, 0, 0, 1]), "peg": Pose([0.2, 0.0, 0.9], [0, 0, 0, 1])}
    env = SimpleNamespace(world=SimpleNamespace(object_poses=lambda: truth), next_skill=2,
                          grasps=SimpleNamespace(holding=lambda: "peg"), model_symmetry=lambda k: "none",
                          estimate_poses=lambda: {"nut": turned, "peg": Pose([0.0, 0.0, 0.9], [0, 0, 0, 1])})
    looks = diagnose._record_look_errors(env)
    env.estimate_poses()
    ((skill, errs),) = looks
    assert skill == 2 and set(errs) == {"nut"}  # the held peg's belief is not a look at it
    assert errs["nut"] == pytest.approx((10.0, 45.0))


def test_diagnose_tally_groups_attempts_by_the_last_skills_demo_and_the_failing_skill():
    from types import SimpleNamespace

    from bench.datagen.attempt_tally import Tally

    def result(ok, demos, reason="OK", message="", used=()):
        return SimpleNamespace(success=ok, source_demos=demos, reason=SimpleNamespace(value=reason),
                               message=message, initiation_candidates_used=list(used), episode=None)

    t = Tally("Square", stages=False)
    touching = [1]
    t.add(result(True, [0, 3]), None, None, touching)
    t.add(result(False, [1, 3], "TASK_FAILED", "nut not on its peg", used=(1, 1)), None, None, [0])
    t.add(result(False, [2], "PLAN_FAILED", "START_IN_COLLISION", used=(1,)), None, None, touching)
    s = t.summary()
    assert s["successes"] == 1 and s["successful_indices"] == [0]
    assert s["by_source_demo"] == {"2": {"successes": 0, "attempts": 1}, "3": {"successes": 1, "attempts": 2}}
    assert s["failures_at_skill"] == {"PLAN_FAILED at skill 0": 1, "TASK_FAILED at skill 1": 1}
    assert s["failures"] == {"TASK_FAILED: nut not on its peg": 1, "PLAN_FAILED: START_IN_COLLISION": 1}
    assert t.touched == [2, 1]  # two attempts touched, one of them succeeded
    assert s["attempts_dragging"] == 0 and "task_failed_stages" not in s


def test_another_contact_models_cells_sit_beside_the_default_models_in_task_order():
    from bench.readme_table import contact_model_rows

    def cells(sg, mg):
        out = [dict(_cell(t, v, "skillgen", sg), wilson95=[0, 1]) for t, v in MARGIN_CELLS]
        return out + [dict(_cell(t, v, "mimicgen", mg), wilson95=[0, 1]) for t, v in MARGIN_CELLS]

    stock = {"cells": cells(0.5, 0.4)}
    pads = {"contact_model": "robosuite_pads", "cells": cells(0.7, 0.4)[::-1]}  # in completion order
    rows = contact_model_rows(stock, pads)
    table = [r for r in rows if r.startswith("| ") and not r.startswith("| task")]
    assert [r.split(" | ")[:2] for r in table] == [["| " + t, v] for t, v in MARGIN_CELLS]
    assert table[0].split(" | ")[2:4] == ["50.0% (0-100)", "70.0% (0-100)"]
    assert rows[-1].startswith("- skillgen vs mimicgen, Square/Threading/NutAssembly D1-D2: 70.0 vs 40.0 (+30.0) on "
                               "`robosuite_pads`, 50.0 vs 40.0 (+10.0) on `pybullet`")
    pads["cells"] = pads["cells"][1:]  # a margin cell missing: no margin line
    assert not contact_model_rows(stock, pads)[-1].startswith("- skillgen vs mimicgen")
    assert contact_model_rows(stock, {"cells": []}) == []


def test_three_piece_stage_places_each_failure_by_where_piece_1_was_lost():
    """diagnose --stages for Three Piece Assembly: a piece carried over the base is not seated in it; one seated
    and later swept off is told apart from one never seated; piece 2's x-y miss is binned in cm."""
    import numpy as np

    from bench.datagen.attempt_tally import STAGES

    stage = STAGES["ThreePieceAssembly"]
    table, up = -0.07, 0.15

    def obs(p1, p2):  # per-step (x, y, z) of each piece; the base stays at (0.56, 0, table)
        n = len(p1)
        pose = lambda xyz: np.c_[np.asarray(xyz, float), np.tile([0, 0, 0, 1.0], (n, 1))]
        return {"base_pose": pose([[0.56, 0.0, table]] * n), "piece_1_pose": pose(p1), "piece_2_pose": pose(p2)}

    rest2 = [[0.4, 0.2, table]] * 4
    assert stage(obs([[0.4, -0.2, table]] * 4, rest2)) == "1 piece_1 never lifted"
    over = [[0.4, -0.2, table], [0.56, 0.0, up], [0.7, 0.1, up], [0.75, 0.1, table]]
    assert stage(obs(over, rest2)).startswith("2 piece_1 lifted, never seated; it ends over 5 cm")
    rim = [[0.4, -0.2, table], [0.56, 0.0, up], [0.59, 0.0, up], [0.59, 0.0, table + 0.02]]
    assert stage(obs(rim, rest2)).startswith("2 piece_1 lifted, never seated; it ends within 5 cm")
    swept = [[0.4, -0.2, table], [0.56, 0.0, up], [0.56, 0.0, table], [0.62, 0.05, table]]
    assert stage(obs(swept, rest2)) == "3 piece_1 on the base, knocked off later"
    seated = [[0.4, -0.2, table], [0.56, 0.0, up], [0.56, 0.0, table], [0.56, 0.0, table]]
    assert stage(obs(seated, rest2)) == "4 piece_2 never lifted"
    beside = [[0.4, 0.2, table], [0.4, 0.2, up], [0.6, 0.0, up], [0.595, 0.0, table + 0.05]]
    assert stage(obs(seated, beside)) == "5 piece_2 beside piece_1, x-y miss 3-4 cm"


def test_slips_measure_how_far_a_held_object_moved_in_the_hand_between_grasp_and_release():
    """diagnose's in-hand slip: the object's position in the EE frame while held, from 3 steps after the close
    until the hand opens; a hand that turns with its object is no slip, an object lagging the hand is."""
    from types import SimpleNamespace

    import numpy as np
    from scipy.spatial.transform import Rotation

    from bench.datagen.attempt_tally import slips
    from skillgen_ros.core.tasks import get_task

    spec = get_task("ThreePieceAssembly")
    n = 20
    skill = np.r_[[0] * 8, [1] * 12]
    grip = np.r_[[-1.0] * 5, [1.0] * 12, [-1.0] * 3]  # closes at 5 (grasp skill), opens at 17 (in skill 1)
    ee = np.c_[np.linspace(0.4, 0.6, n), np.zeros(n), np.full(n, 0.1)]
    yaw = Rotation.from_euler("z", np.linspace(0.0, 1.0, n)[:, None])
    below = yaw.apply([0.0, 0.0, -0.03])  # the piece 3 cm below the grasp point, turning with the hand
    p1 = ee + below
    p1[12:17, 0] -= 0.015  # lags the hand by 1.5 cm for five steps, while held
    quat = yaw.as_quat()
    pose = lambda p: np.c_[p, quat]
    p2 = np.tile([0.5, 0.2, -0.07, 0, 0, 0, 1.0], (n, 1))
    ep = SimpleNamespace(labels={"skill_index": skill}, actions_abs=np.c_[np.zeros((n, 7)), grip],
                         obs={"robot0_eef_pos": ee, "robot0_eef_quat": quat, "piece_1_pose": pose(p1),
                              "piece_2_pose": p2})
    out = slips(ep, spec)
    assert set(out) == {"piece_1"} and abs(out["piece_1"] - 0.015) < 1e-9
    p1[12:17, 0] += 0.015
    p1[18:] += 0.1  # moved after the hand opened: not a slip
    ep.obs["piece_1_pose"] = pose(p1)
    assert slips(ep, spec)["piece_1"] < 1e-9

"""bench/hsp: a run stopped between a chunk's training and its evaluation loses no result (run.py), and
retraining one network of a checkpoint keeps the others bit for bit (retrain.py), and the skill
diagnosis names which on_peg condition a placement failed (skill_diagnosis.py).

The benchmark records a chunk's training before evaluating it (evaluations take minutes); when the
session ends in between, the rerun must evaluate that chunk before training on (or when training had
finished), and only for the methods that lack it.
"""
from __future__ import annotations

import sys
from types import SimpleNamespace

from conftest import REPO

sys.path.insert(0, str(REPO))
from bench.hsp import retrain, run  # noqa: E402


def _store(tmp_path, evals):
    s = run.Store.__new__(run.Store)
    s.path, s.data = tmp_path / "hsp.json", {"cells": {}}
    c = s.cell("Threading/D0")
    for m, steps in evals.items():
        c["methods"][m] = {"evals": [{"step": k} for k in steps]}
    return s


def _calls(monkeypatch):
    calls = []
    monkeypatch.setattr(run, "evaluate_methods", lambda store, cell, net, ckpt, step, methods, a:
                        calls.append((step, list(methods))))
    return calls


def test_an_unevaluated_chunk_is_evaluated_for_the_methods_that_lack_it(tmp_path, monkeypatch):
    calls = _calls(monkeypatch)
    kept = tmp_path / "step_013500.pt"
    kept.write_bytes(b"x")
    store = _store(tmp_path, {"HSP-TAMP": [4500, 9000, 13500], "HSP-Class": [4500, 9000]})
    run._evaluate_unevaluated(store, "Threading/D0", "hsp", kept, 13500,
                              ["HSP-TAMP", "HSP-Class", "HSP-Reg"], SimpleNamespace())
    assert calls == [(13500, ["HSP-Class", "HSP-Reg"])]


def test_nothing_to_evaluate_when_done_untrained_or_the_checkpoint_is_gone(tmp_path, monkeypatch):
    calls = _calls(monkeypatch)
    kept = tmp_path / "step_009000.pt"
    store = _store(tmp_path, {"HSP-TAMP": [4500, 9000]})
    run._evaluate_unevaluated(store, "Threading/D0", "hsp", kept, 9000, ["HSP-TAMP"], SimpleNamespace())
    run._evaluate_unevaluated(store, "Threading/D0", "hsp", kept, 0, ["HSP-Reg"], SimpleNamespace())
    run._evaluate_unevaluated(store, "Threading/D0", "hsp", kept, 9000, ["HSP-Reg"], SimpleNamespace())  # no file
    assert calls == []


def test_retraining_t_on_settled_labels_keeps_pi_and_records_the_rule(tmp_path_factory, tmp_path):
    import dataclasses

    import torch
    from _learning_data import generated_dataset, tiny_checkpoint

    from skillgen_ros.core.learning.checkpoint import load_hsp, read_checkpoint

    src = tiny_checkpoint(tmp_path_factory, generated_dataset(tmp_path_factory))
    cfg = read_checkpoint(src)[0]
    cfg = dataclasses.replace(cfg, train=dataclasses.replace(cfg.train, termination_labels="settled"))
    rec = retrain.retrain_network(str(src), cfg, "termination", str(tmp_path / "t.pt"), 3, 0)
    assert rec["steps"] == 3 and rec["train_loss_last_epoch"] > 0  # 3 demos: no validation split
    old, new = load_hsp(src), load_hsp(tmp_path / "t.pt")
    assert new.config.train.termination_labels == "settled" and old.config.train.termination_labels == "paper"
    for (k, a), (_, b) in zip(old.nets["policy"].state_dict().items(), new.nets["policy"].state_dict().items()):
        assert torch.equal(a, b), k
    assert any(not torch.equal(a, b) for a, b in zip(old.nets["termination"].state_dict().values(),
                                                     new.nets["termination"].state_dict().values()))
    retrain.record(tmp_path / "r.json", "Square/D0/settled", rec, {"cpu": "test"})
    import json
    assert json.loads((tmp_path / "r.json").read_text())["runs"]["Square/D0/settled"]["steps"] == 3


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


def test_both_retrain_scripts_share_one_parser_and_record_the_rerun_command():
    from bench.hsp import retrain_reg, retrain_termination

    assert retrain_reg.retrain_parser is retrain_termination.retrain_parser is retrain.retrain_parser
    p = retrain.retrain_parser("Retrain X.\n\nmore", "X", "out.json")
    a = p.parse_args(["--checkpoint", "c.pt", "--rollouts", "7"])
    assert (a.checkpoint, a.steps, a.seed, a.rollouts, a.out) == ("c.pt", 0, 0, 7, "out.json")
    assert retrain.rerun_command("bench/hsp/retrain_reg.py", ["--checkpoint", "a b.pt"]) == \
        ".venv/bin/python bench/hsp/retrain_reg.py --checkpoint 'a b.pt'"
    s = SimpleNamespace(to_json=lambda: {"success_rate": 0.5, "reset_seeds": [1, 2]})
    assert retrain.evaluation_record(s, 3.0) == {"success_rate": 0.5, "eval_seconds": 3.0}


def test_skill_diagnosis_names_which_on_peg_condition_failed():
    from bench.hsp import skill_diagnosis as sd

    assert sd.placement(0.01, 0.02) == "seated"  # centred and down the peg: robosuite on_peg
    assert sd.placement(0.01, 0.119) == "on_top"  # centred, resting on the 13 cm peg's top
    assert sd.placement(0.03, 0.02) == "beside"  # on_peg's |dx|, |dy| < 3 cm is strict
    rows = [{"success": False, "reason": "POLICY_TIMEOUT", "skills": {"1": {"ended": "budget", "placement": "on_top", "closed_steps": 87},
                                          "2": {"ended": "budget", "closed_steps": 0}}},
            {"success": True, "reason": "OK", "skills": {"1": {"ended": "goal", "placement": "seated", "closed_steps": 60},
                                         "2": {"ended": "goal", "closed_steps": 5}}}]
    s = sd.summarize(rows)
    assert s["successes"] == 1 and s["skills"]["1"]["placement"] == {"on_top": 1, "seated": 1}
    assert s["reasons"] == {"POLICY_TIMEOUT": 1, "OK": 1}
    assert s["skills"]["2"]["never_closed"] == 1 and s["skills"]["2"]["ended"] == {"budget": 1, "goal": 1}

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

import pytest

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


def test_the_diagnostics_share_one_rollout_loop_over_the_benchmarks_reset_seeds(tmp_path_factory):
    from _learning_data import generated_dataset, tiny_checkpoint

    from bench.hsp import bc_diagnosis, diagnosis, skill_diagnosis
    from skillgen_ros.core.deploy.seeds import rollout_seed

    assert bc_diagnosis.diagnose_rollouts is skill_diagnosis.diagnose_rollouts is diagnosis.diagnose_rollouts
    src = tiny_checkpoint(tmp_path_factory, generated_dataset(tmp_path_factory))
    seen = []

    def make_row(env, policy, spec):
        seen.append(env)
        return lambda seed: {"seed": seed, "task": spec.name, "variant": policy.config.variant}

    policy, spec, rows = diagnosis.diagnose_rollouts(str(src), 3, 2, make_row)
    assert [r["seed"] for r in rows] == [rollout_seed(3, 0), rollout_seed(3, 1)]
    assert rows[0]["task"] == spec.name == policy.config.task and len(seen) == 1


def test_keypoint_world_is_the_point_the_success_rules_read():
    import numpy as np

    from skillgen_ros.core.geometry import Pose
    from skillgen_ros.core.tasks import get_task, suite

    spec = get_task("Square")
    nut = spec.objects[0]
    pose = Pose([0.1, -0.2, 0.9], [0.0, 0.0, np.sin(0.4), np.cos(0.4)])  # turned 46 deg about z
    local = np.asarray(nut.keypoint("body_origin"), float)
    np.testing.assert_allclose(suite.keypoint_world(nut, pose, "body_origin"),
                               pose.matrix()[:3, :3] @ local + pose.position, atol=1e-12)


def test_parallel_shards_are_fixed_attempt_ranges_sized_by_the_rate_so_far():
    from bench.hsp.shards import PRIOR_RATE, next_batch

    assert next_batch([], 1000, 100, 1, 5) == [(0, 500, 100)]  # one worker: stop at 100 successes, cap 5x
    size = -(-100 // PRIOR_RATE)
    assert next_batch([], 1000, 100, 2, 5) == [(0, size, 0), (size, size, 0)]
    done = [{"attempts": 400, "successes": 100}, {"attempts": 400, "successes": 100}]  # 25% so far
    assert next_batch(done, 1000, 100, 2, 5) == [(800, 400, 0), (1200, 400, 0)]
    # 50 to go at 25%: ~200 attempts, split over both workers (one shard would leave a core idle)
    assert next_batch(done, 250, 100, 2, 5) == [(800, 100, 0), (900, 100, 0)]
    assert next_batch(done, 201, 100, 2, 5) == [(800, 2, 0), (802, 2, 0)]  # 1 to go
    assert next_batch(done, 200, 100, 2, 5) == []


def test_two_generation_workers_write_the_dataset_one_worker_writes(tmp_path, monkeypatch):
    """The first N successes in attempt order, whatever the split: the same demos, bit for bit."""
    import h5py
    import numpy as np

    from bench.hsp import shards
    from skillgen_ros.core.dataset.hdf5 import merge_datasets

    monkeypatch.setattr(shards, "PRIOR_RATE", 0.9)  # small batches: Square D0 succeeds ~90%
    merged = {}
    for workers in (1, 2):
        root, recs = tmp_path / f"w{workers}", []

        def job_of(first, attempts, want, out):
            return shards.ShardJob("Square", "D0", "skillgen", False, 7, first, attempts, want, out)
        files = shards.generate(recs, root, job_of, 3, 2, workers, 5, lambda: None)
        merged[workers] = str(root / "demo.hdf5")
        merge_datasets(files, merged[workers], keep=shards.first_n_keep(files, 3))
        assert sum(r["successes"] for r in recs) >= 3
    assert shards.demo_indices([merged[1]]) == shards.demo_indices([merged[2]])
    assert len(shards.demo_indices([merged[1]])) == 3
    with h5py.File(merged[1], "r") as a, h5py.File(merged[2], "r") as b:
        for name in a["data"]:
            np.testing.assert_array_equal(a["data"][name]["actions"][()], b["data"][name]["actions"][()])
            np.testing.assert_array_equal(a["data"][name]["obs"]["robot0_eef_pos"][()],
                                          b["data"][name]["obs"]["robot0_eef_pos"][()])


def test_evaluation_rollouts_split_over_workers_summarize_as_one_process(tmp_path_factory):
    from _learning_data import generated_dataset, tiny_checkpoint

    from bench.hsp.evaluation import evaluate_modes, split
    from skillgen_ros.core.deploy import evaluate

    assert split(50, 2) == [(0, 25), (25, 25)] and split(5, 3) == [(0, 2), (2, 1), (3, 2)] and split(1, 2) == [(0, 1)]
    src = str(tiny_checkpoint(tmp_path_factory, generated_dataset(tmp_path_factory)))
    one = evaluate(src, "Square", "D0", "tamp", 2, 5)
    (two,) = evaluate_modes(src, "Square", "D0", ["tamp"], 2, 5, "cpu", 2).values()
    a, b = one.to_json(), two.to_json()
    a.pop("inference_ms_per_step"), b.pop("inference_ms_per_step")  # timing, not outcome
    assert a == b and a["reset_seeds"] == [r.reset_seed for r in two.results]


def test_a_network_resumed_under_a_new_record_times_only_the_steps_it_trained(tmp_path, monkeypatch):
    """A network resumed at 13.5k from an earlier run's last.pt, under a new --out, trains two 4.5k chunks:
    ms_per_train_step divides this record's seconds by the 9k steps they cover, not by 22.5k."""
    from skillgen_ros.core.learning import trainer

    a = SimpleNamespace(work=str(tmp_path), demos=1000, hidden=400, mlp_hidden=[1024, 1024], budget_steps=22500,
                        budget_minutes=0, steps_per_epoch=100, device="cpu", seed=0, threads=1, chunk_steps=4500)
    out = run.net_dir("NutAssembly/D1", "hsp", a)
    out.mkdir(parents=True)
    step = {"now": 13500}

    def fake_train(req):
        step["now"] += req.stop_after
        last = out / "last.pt"
        last.write_bytes(b"x")
        return SimpleNamespace(config=SimpleNamespace(step=step["now"]), finished=False, last_path=str(last))

    clock = iter(range(0, 10_000, 100))  # every time.time() call is 100 s after the last
    monkeypatch.setattr(trainer, "train", fake_train)
    monkeypatch.setattr(run, "_trained_steps", lambda last: step["now"])
    monkeypatch.setattr(run.time, "time", lambda: float(next(clock)))
    calls = _calls(monkeypatch)
    store = _store(tmp_path, {})
    store.save = lambda: None
    (out / "last.pt").write_bytes(b"x")
    run.train_network(store, "NutAssembly/D1", "hsp", "data.hdf5", ["HSP-TAMP"], a)
    rec = store.cell("NutAssembly/D1")["networks"]["hsp"]
    assert [c[0] for c in calls] == [18000, 22500]
    assert (rec["steps"], rec["timed_steps"], rec["train_seconds"]) == (22500, 9000, 200.0)
    assert abs(rec["ms_per_train_step"] - 1000 * 200 / 9000) < 1e-9
    from bench.machine import cpu_model
    assert rec["cpu_models"] == [cpu_model()]  # a network resumed on another machine would list both


def test_a_run_of_some_methods_keeps_the_other_methods_rows_in_the_cells_table(tmp_path, monkeypatch):
    """The baseline run after the HSP run (or a second process's part) rewrites the cell's table from every
    method with a best evaluation, not only its own."""
    store = _store(tmp_path, {})
    store.save = lambda: None
    c = store.cell("Square/D2")
    c["methods"]["HSP-Class"] = {"evals": [], "best": {"success_rate": 0.26}}
    monkeypatch.setattr(run, "make_dataset", lambda store, cell, network, a: "data.hdf5")

    def fake_train(store, cell, network, dataset, methods, a):
        for m in methods:
            store.cell(cell)["methods"][m] = {"evals": [], "best": {"success_rate": 0.06}}

    monkeypatch.setattr(run, "train_network", fake_train)
    a = SimpleNamespace(methods=["MimicGen-BC"], demos=1000, rollouts=50, seed=0, budget_steps=13500,
                        chunk_steps=4500, device="cpu", hidden=400, mlp_hidden=[1024, 1024], hsp_data="ia",
                        work=str(tmp_path), out=str(tmp_path / "hsp.json"), budget_minutes=0, threads=0,
                        datasets_from=str(run.ROOT / "bench/results/hsp_v2.json"))
    run.run_cell(store, "Square/D2", a)
    assert {m: r["success_rate"] for m, r in c["table"].items()} == {"HSP-Class": 0.26, "MimicGen-BC": 0.06}
    # its rerun command runs this part again, on the datasets it was given, not every method on new data
    assert c["rerun"].endswith("--methods MimicGen-BC --datasets-from bench/results/hsp_v2.json")


def test_a_barren_tail_batch_retries_and_only_a_long_barren_run_gives_up(tmp_path, monkeypatch):
    """A tail batch of a few attempts may have no success; generation goes on until `shard * cap`
    attempts in a row had none (it used to give up on the first empty batch, however small)."""
    import pytest

    from bench.hsp import shards as S
    from skillgen_ros.core.generation import sim_env

    monkeypatch.setattr(sim_env, "SimGenerationEnv", lambda *a, **k: SimpleNamespace(close=lambda: None))
    plan = iter([5, 0, 1])  # successes of successive shards: 5 of 6 needed, then a barren tail, then the last one

    def fake_shard(job, env=None, demos=None):
        n = next(plan)
        return {"dir": job.out, "first_index": job.first, "attempts": max(n, 1) * 2, "successes": n}

    monkeypatch.setattr(S, "generate_shard", fake_shard)

    def job_of(first, n, want, out):
        return S.ShardJob("Square", "D0", "skillgen", False, 0, first, n, want, out)

    recs = []
    S.generate(recs, tmp_path, job_of, demos=6, shard=5, workers=1, cap_factor=5, save=lambda: None)
    assert [r["successes"] for r in recs] == [5, 0, 1]

    plan = iter([0] * 30)  # nothing ever succeeds: give up after shard * cap = 25 barren attempts
    with pytest.raises(SystemExit, match="no successes in the last"):
        S.generate([], tmp_path, job_of, demos=6, shard=5, workers=1, cap_factor=5, save=lambda: None)


def test_merging_a_cell_new_to_the_table_brings_its_paper_numbers_and_rerun_command(tmp_path):
    """--merge-from: another process's methods of one cell, with what the README row needs; another protocol
    is refused and the table stays as it was."""
    import json

    best = {"successes": 10, "rollouts": 50, "success_rate": 0.2, "wilson95": [0.11, 0.33], "step": 9300}
    part = {"protocol": {"demos": 1000, "threads": 2}, "cells": {"Threading/D1": {
        "rerun": "bench/hsp/run.py --cells Threading/D1", "paper": run.PAPER["Threading/D1"],
        "datasets": {"hsp": {"demos": 1000}}, "networks": {"hsp": {"steps": 13500}},
        "methods": {m: {"best": best} for m in ("HSP-TAMP", "HSP-Class", "HSP-Reg")}}}}
    src, dst = tmp_path / "part.json", tmp_path / "hsp.json"
    src.write_text(json.dumps(part))
    dst.write_text(json.dumps({"protocol": {"demos": 1000, "threads": 1}, "cells": {}}))
    a = SimpleNamespace(cells=["Threading/D1"], methods=["HSP-TAMP", "HSP-Class", "HSP-Reg"])
    assert run.merge_from(src, dst, a) == 0
    c = json.loads(dst.read_text())["cells"]["Threading/D1"]
    assert c["paper"] == {"MimicGen-BC": 60.7, "HSP-TAMP": 72, "HSP-Class": 66, "HSP-Reg": 60}
    assert c["rerun"] == part["cells"]["Threading/D1"]["rerun"] and c["table"]["HSP-TAMP"] == best
    assert c["methods"]["HSP-Reg"]["merged_from"] == "part.json" and "MimicGen-BC" not in c["table"]
    before = dst.read_text()
    part["protocol"]["demos"] = 200
    src.write_text(json.dumps(part))
    with pytest.raises(SystemExit, match=r"another protocol \(\['demos'\]\)"):
        run.merge_from(src, dst, a)
    assert dst.read_text() == before


def test_a_lost_shard_regenerated_to_another_count_keeps_its_range_and_records_both(tmp_path, monkeypatch):
    """out/ gone: a recorded shard is redone over its attempt range. Another CPU's numerics may change its
    success count (83 -> 70 of 500 on Threading D1's BC): the record takes the new count, keeps the old one,
    keeps its range, is saved at once, and the next shard starts after that range."""
    from bench.hsp import shards as S
    from skillgen_ros.core.generation import sim_env

    monkeypatch.setattr(sim_env, "SimGenerationEnv", lambda *a, **k: SimpleNamespace(close=lambda: None))
    calls = []

    def fake_shard(job, env=None, demos=None):
        calls.append((job.first, job.attempts, job.want))
        ok = 3 if job.first == 0 else job.want  # the lost shard comes back with 3 where 5 were recorded
        return {"dir": job.out, "first_index": job.first, "attempts": job.attempts, "successes": ok, "seconds": 1.0}

    monkeypatch.setattr(S, "generate_shard", fake_shard)

    def job_of(first, n, want, out):
        return S.ShardJob("Square", "D0", "skillgen", False, 0, first, n, want, out)

    recs = [{"dir": str(tmp_path / "shard_000"), "first_index": 0, "attempts": 10, "successes": 5, "seconds": 9.0,
             "fixed": True}]
    saved = []
    S.generate(recs, tmp_path, job_of, demos=8, shard=5, workers=1, cap_factor=5,
               save=lambda: saved.append([dict(r) for r in recs]))
    assert calls[0] == (0, 10, 0)  # the lost range, fixed: every attempt of it
    assert recs[0]["successes"] == 3 and recs[0]["attempts"] == 10
    assert recs[0]["regenerated_from"] == {"successes": 5, "seconds": 9.0}
    assert saved[0][0]["successes"] == 3  # saved before any new shard ran
    assert calls[1][0] == 10 and recs[1]["first_index"] == 10  # the next range starts after the lost one
    assert sum(r["successes"] for r in recs) >= 8


def test_a_recorded_shard_whose_file_holds_other_demos_takes_the_files_count(tmp_path):
    """A regeneration written but not recorded (an earlier version stopped there): the record takes the file's
    count and keeps its own under regenerated_from; a file that agrees, a lost one and an empty shard are left."""
    import h5py

    from bench.hsp import shards as S

    recs = []
    for k, (held, recorded) in enumerate([(3, 5), (4, 4), (None, 2), (None, 0)]):
        d = tmp_path / f"shard_{k:03d}"
        d.mkdir()
        if held is not None:
            with h5py.File(d / "demo.hdf5", "w") as f:
                for i in range(held):
                    f.create_group(f"data/demo_{i}")
        recs.append({"dir": str(d), "first_index": 10 * k, "attempts": 10, "successes": recorded, "seconds": 1.0})
    assert S.reconcile(recs)
    assert [r["successes"] for r in recs] == [3, 4, 2, 0]
    assert recs[0]["regenerated_from"] == {"successes": 5, "seconds": 1.0}
    assert all("regenerated_from" not in r for r in recs[1:])
    assert not S.reconcile(recs)

"""`skillgen deploy --in-process` and `evaluate` (the trainer's rollout hook) on a tiny checkpoint."""
import json

import pytest
from _learning_data import generated_dataset, tiny_checkpoint

from skillgen_ros.cli.deploy import main
from skillgen_ros.core.deploy import DeployConfig, evaluate, rollout_seed


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    return tiny_checkpoint(tmp_path_factory, generated_dataset(tmp_path_factory))


def test_in_process_deploy_prints_a_wilson_interval_and_writes_results(checkpoint, tmp_path, capsys):
    out = tmp_path / "eval"
    rc = main(["--checkpoint", str(checkpoint), "--task", "Square", "--variant", "D0", "--rollouts", "2",
               "--seed", "3", "--max-steps", "200", "--in-process", "--output", str(out)])
    text = capsys.readouterr().out
    assert rc == 0 and "Wilson" in text and "rollout 1:" in text, text
    r = json.loads((out / "results.json").read_text())
    assert r["rollouts"] == 2 and r["mode"] == "class" and len(r["wilson_95"]) == 2
    assert r["reset_seeds"] == [rollout_seed(3, 0), rollout_seed(3, 1)]
    assert sum(r["failures"].values()) == 2 - r["successes"]
    assert "skillgen deploy" in r["command"]


@pytest.mark.parametrize("args, reason", [(["--checkpoint", "/nonexistent.pt"], "BAD_CHECKPOINT"),
                                          (["--task", "NoSuchTask"], "UNKNOWN_TASK"),
                                          (["--mode", "teleport"], "UNKNOWN_MODE"),
                                          (["--mode", "reg"], "BAD_CHECKPOINT"),
                                          (["--variant", "D9"], "UNKNOWN_VARIANT")])
def test_bad_arguments_exit_2_with_the_reason(checkpoint, tmp_path, capsys, args, reason):
    base = {"--checkpoint": str(checkpoint), "--task": "Square", "--variant": "D0"}
    base.update(dict(zip(args[::2], args[1::2])))
    argv = [x for kv in base.items() for x in kv] + ["--rollouts", "1", "--in-process", "--output", str(tmp_path)]
    if "--mode" in args:
        argv += ["--mode", args[1]]
    assert main(argv) == 2
    assert reason in capsys.readouterr().err


def test_evaluate_with_only_a_path_is_the_trainers_hook(checkpoint):
    s = evaluate(str(checkpoint), rollouts=1, config=DeployConfig(max_steps=120))
    assert (s.task, s.variant, s.mode, s.rollouts) == ("Square", "D0", "class", 1)
    assert 0.0 <= float(s) <= 1.0 and s.results[0].reset_seed == rollout_seed(0, 0)

"""The scripted demonstrator: smooth, seeded, different from demo to demo, and it solves the task."""
from __future__ import annotations

import numpy as np
import pytest

from skillgen_ros.core.demonstrator import DemoStyle, ScriptedDemonstrator
from skillgen_ros.core.demonstrator.motion import min_jerk, nearest_yaw, reach
from skillgen_ros.core.geometry import Pose


def test_min_jerk_profile_is_smooth_and_bounded():
    t = np.linspace(0, 1, 201)
    s = min_jerk(t)
    assert s[0] == 0 and s[-1] == 1 and np.all(np.diff(s) >= 0)
    v = np.gradient(s, t)
    assert abs(v[0]) < 1e-3 and abs(v[-1]) < 1e-3 and abs(v.max() - 1.875) < 1e-2  # bell-shaped speed
    path = reach(Pose([0, 0, 0], [0, 0, 0, 1]), Pose([0.1, 0, 0], [0, 0, 0.7071068, 0.7071068]), 20)
    assert len(path) == 20 and np.allclose(path[-1].position, [0.1, 0, 0])
    assert nearest_yaw(0.1, np.pi / 2, 3.0) == 0.1 + np.pi


def test_styles_are_seeded_and_vary():
    a = DemoStyle.sample(np.random.default_rng(1))
    b = DemoStyle.sample(np.random.default_rng(1))
    c = DemoStyle.sample(np.random.default_rng(2))
    assert repr(a) == repr(b) and repr(a) != repr(c)


def test_demonstrator_is_deterministic_per_seed_and_succeeds():
    from skillgen_ros.core.sim import SimWorld

    world = SimWorld()
    try:
        r1 = ScriptedDemonstrator("PickPlace", 7).run(world, "D0", 1003)
        r2 = ScriptedDemonstrator("PickPlace", 7).run(world, "D0", 1003)
        r3 = ScriptedDemonstrator("PickPlace", 8).run(world, "D0", 1003)
    finally:
        world.close()
    assert r1.success and r2.success
    t1 = np.array([s.target for s in r1.steps])
    assert np.array_equal(t1, np.array([s.target for s in r2.steps]))
    assert len(r3.steps) != len(r1.steps) or not np.allclose(t1, [s.target for s in r3.steps])
    step = np.linalg.norm(np.diff(t1[:, :3], axis=0), axis=1)
    assert step.max() < 0.03, "targets must move smoothly (< 3 cm per 50 ms control period)"


def _rise_after_open(rollout) -> int:
    """Control steps from the (last) open command until the hand is 1 cm higher."""
    g = np.array([s.gripper_command for s in rollout.steps])
    z = np.array([s.ee_pose[2] for s in rollout.steps])
    k = int(np.flatnonzero((g[1:] < 0) & (g[:-1] > 0))[-1]) + 1
    return int(np.flatnonzero(z[k:] > z[k] + 0.01)[0])


def test_prompt_retreat_rises_within_ten_steps_of_the_open_and_changes_nothing_before_it():
    """PROMPT_RETREAT (off for the shipped demos): the hand is 1 cm up 8-10 steps after the open, inside MimicGen's
    place-subtask ends (its signal + 5-10 steps); the hold-then-ease style takes 16-22 (bench/datagen/release_hold.py)."""
    from skillgen_ros.core.sim import SimWorld

    world, before = SimWorld(), ScriptedDemonstrator.PROMPT_RETREAT
    try:
        ScriptedDemonstrator.PROMPT_RETREAT = False
        held = ScriptedDemonstrator("PickPlace", 7).run(world, "D0", 1003)
        ScriptedDemonstrator.PROMPT_RETREAT = True
        prompt = ScriptedDemonstrator("PickPlace", 7).run(world, "D0", 1003)
    finally:
        ScriptedDemonstrator.PROMPT_RETREAT = before
        world.close()
    assert held.success and prompt.success
    assert _rise_after_open(prompt) <= 10 < 15 < _rise_after_open(held)
    g = np.array([s.gripper_command for s in held.steps])
    opened = int(np.flatnonzero((g[1:] < 0) & (g[:-1] > 0))[-1]) + 1
    assert np.array_equal([s.target for s in held.steps[:opened]], [s.target for s in prompt.steps[:opened]])


def test_demos_make_cli_writes_annotated_bags_and_subsets(tmp_path, capsys):
    from skillgen_ros.cli import demos
    from skillgen_ros.core.errors import SkillGenError
    from skillgen_ros.core.skills.bag_demos import load_source_demos
    from skillgen_ros.core.tasks import get_task

    # --n 1 with the default subset (min(3, n)): issue 24
    assert demos.main(["make", "--task", "PickPlace", "--n", "1", "--out", str(tmp_path)]) == 0
    paths = demos.subset_paths(tmp_path / "PickPlace", "first1")
    assert [p.name for p in paths] == ["demo_00"] and (paths[0] / "annotations.yaml").is_file()
    (demo,) = load_source_demos(paths, get_task("PickPlace"))
    assert demo.scene_seed == demos.SCENE_SEED_BASE and len(demo.skills) == 2
    with pytest.raises(SkillGenError) as e:  # remaking existing demos needs --force
        demos.main(["make", "--task", "PickPlace", "--n", "1", "--subset", "1", "--out", str(tmp_path)])
    assert e.value.reason == "EXISTS"

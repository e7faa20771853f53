"""Planning randomness: IK draws and OMPL's RRT searches are per call after reseed(s)."""
from pathlib import Path
import numpy as np
import pytest

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.planning.collision import Box, CollisionModel
from skillgen_ros.core.planning.ik import IKSolver
from skillgen_ros.core.planning.kinematics import PandaKinematics
from skillgen_ros.core.planning.planner import Mode, MotionPlanner
from skillgen_ros.core.robot import Q_HOME

DOWN = np.array([1.0, 0.0, 0.0, 0.0])


def _box(name, xyz, half):
    T = np.eye(4)
    T[:3, 3] = xyz
    return Box(name, T, np.asarray(half, float))


WALL = _box("wall", [0.5, 0.0, 0.25], [0.12, 0.015, 0.25])


@pytest.fixture(scope="module")
def world():
    kin = PandaKinematics()
    start = IKSolver(kin, rng=0).solve(Pose([0.5, -0.25, 0.15], DOWN).matrix(), seed_q=Q_HOME,
                                       max_iterations=8000, timeout=300.0).solutions[0]
    return kin, start


def _planner(kin, seed=None):
    cm = CollisionModel(kin)
    cm.set_boxes([WALL])
    return MotionPlanner(kin, IKSolver(kin, rng=seed), cm, seed=seed)


def test_ik_draws_are_per_call_after_reseed(world):
    """The k-th plan after reseed(s) gets the same IK stream whatever ran before."""
    kin, start = world
    p1, p2 = _planner(kin, seed=3), _planner(kin)
    for target in ([0.3, 0.3, 0.25], [0.6, -0.1, 0.2]):  # a history on p1 only
        p1.plan(start, Pose(target, DOWN), Mode.TRANSIT, timeout=5.0)
    p1.reseed(7)
    p2.reseed(7)
    draws = []
    for p in (p1, p2):
        p._reseed_ik_for_call()
        draws.append(p.ik.rng.integers(1 << 30, size=4))
    np.testing.assert_array_equal(draws[0], draws[1])


def test_same_seed_same_plans_in_a_fresh_process(tmp_path):
    """Two fresh processes with the same seed plan the wall problem (which needs RRT) to
    identical paths."""
    import subprocess
    import sys

    script = tmp_path / "plan.py"
    script.write_text(
        "import sys, numpy as np\n"
        f"sys.path.insert(0, {str(Path(__file__).parent)!r})\n"
        "from test_planning_determinism import _planner, WALL, DOWN\n"
        "from skillgen_ros.core.geometry import Pose\n"
        "from skillgen_ros.core.planning.ik import IKSolver\n"
        "from skillgen_ros.core.planning.kinematics import PandaKinematics\n"
        "from skillgen_ros.core.planning.planner import Mode\n"
        "from skillgen_ros.core.robot import Q_HOME\n"
        "kin = PandaKinematics()\n"
        "start = IKSolver(kin, rng=0).solve(Pose([0.5, -0.25, 0.15], DOWN).matrix(), seed_q=Q_HOME, max_iterations=8000, timeout=300.0).solutions[0]\n"
        "r = _planner(kin, seed=5).plan(start, Pose([0.5, 0.25, 0.15], DOWN), Mode.TRANSIT, timeout=5.0)\n"
        "assert r.ok, r.message\n"
        "sys.stdout.write(np.round(r.joint_path, 9).tobytes().hex())\n")
    outs = [subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300)
            for _ in range(2)]
    assert all(o.returncode == 0 for o in outs), outs[0].stderr[-2000:]
    assert outs[0].stdout == outs[1].stdout and outs[0].stdout


def test_rrt_plans_are_per_call_whatever_the_process_planned_before(world):
    """The k-th plan after reseed(s) is the same path in a planner with a history of other RRT
    searches (other seeds, other queries) as in a fresh one: attempts can be sharded."""
    kin, start = world
    goal = Pose([0.5, 0.25, 0.15], DOWN)
    fresh = _planner(kin, seed=11).plan(start, goal, Mode.TRANSIT, timeout=5.0)
    assert fresh.ok, fresh.message
    assert len(fresh.joint_path) > 4  # retreat, approach and at least one RRT waypoint around the wall
    busy = _planner(kin, seed=2)
    for target in ([0.5, 0.3, 0.2], [0.45, 0.2, 0.1]):  # RRT searches around the wall first
        assert busy.plan(start, Pose(target, DOWN), Mode.TRANSIT, timeout=5.0).ok
    busy.reseed(11)
    again = busy.plan(start, goal, Mode.TRANSIT, timeout=5.0)
    assert again.ok, again.message
    np.testing.assert_array_equal(again.joint_path, fresh.joint_path)


def test_an_rrt_iteration_budget_ends_the_same_search_however_slow_the_machine(world):
    """RRT-Connect budgeted in iterations: a search slowed down (a checker that sleeps, as a loaded
    CPU would) grows the same trees to the same path, and a budget too small for the wall ends
    the search after it (at the iteration budget, not the 30 s timeout). No wall-clock comparison:
    'slower' is the slow checker's own count of the sleeps it added (a suite run at load ~6 made the
    plain search slower than the slowed one's margin)."""
    import time

    from skillgen_ros.core.planning.rrt import JointSpaceRRT, RRTStatus

    kin, start = world
    goal = IKSolver(kin, rng=0).solve(Pose([0.5, 0.25, 0.15], DOWN).matrix(), seed_q=Q_HOME,
                                      max_iterations=8000, timeout=300.0).solutions[0]
    cm = CollisionModel(kin)
    cm.set_boxes([WALL])
    slept = [0]

    def slow(q0, q1):
        time.sleep(0.002)  # a slow checker (work, not synchronisation): the plan must not change
        slept[0] += 1
        return cm.check_motion(q0, q1)

    rrt = JointSpaceRRT(kin.lower, kin.upper)
    runs = [rrt.plan(start, goal, cm.in_collision, check, 30.0, seed=4, max_iterations=100)
            for check in (cm.check_motion, slow)]
    assert all(r.status is RRTStatus.SOLVED for r in runs) and runs[0].iterations > 2
    assert slept[0] > 0  # the slowed search really went through the sleeping checker
    assert runs[0].iterations == runs[1].iterations
    np.testing.assert_array_equal(runs[0].path, runs[1].path)
    cut = rrt.plan(start, goal, cm.in_collision, cm.check_motion, 30.0, seed=4, max_iterations=2)
    assert cut.status is RRTStatus.TIMEOUT and cut.iterations == 3


def test_a_plan_seed_draws_as_the_kth_plan_after_reseed_and_leaves_the_count(world):
    """plan(seed=(s, k)) (the planner node's seeded requests) plans what the k-th plan after
    reseed(s) plans, and the planner's own count goes on as if that plan had not happened."""
    kin, start = world
    goal = Pose([0.5, 0.25, 0.15], DOWN)
    ref = _planner(kin, seed=11)
    ref.plan(start, Pose([0.45, 0.2, 0.1], DOWN), Mode.TRANSIT, timeout=5.0)  # plan 0
    expected = ref.plan(start, goal, Mode.TRANSIT, timeout=5.0)  # plan 1
    other = _planner(kin, seed=4)
    got = other.plan(start, goal, Mode.TRANSIT, timeout=5.0, seed=(11, 1))
    assert got.ok and expected.ok
    np.testing.assert_array_equal(got.joint_path, expected.joint_path)
    assert other._calls == 0
    for bad in ((11,), (11, -1), (True, 1), (1.5, 0)):
        with pytest.raises(InvalidInputError):
            other.plan(start, goal, Mode.TRANSIT, timeout=5.0, seed=bad)


def test_reseed_rejects_bad_seeds(world):
    kin, _ = world
    planner = _planner(kin)
    for bad in (-1, 1.5, "7", None):
        with pytest.raises(InvalidInputError):
            planner.reseed(bad)

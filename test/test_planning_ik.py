"""TRAC-IK-style solver: round trips on reachable poses, limits respected, collision-aware."""
import numpy as np
import pytest

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.planning.ik import IKSolver, IKStatus
from skillgen_ros.core.planning.kinematics import PandaKinematics


@pytest.fixture(scope="module")
def kin():
    return PandaKinematics()


def _pose_error(kin, q, T):
    Tq = kin.fk(q)
    dp = np.linalg.norm(Tq[:3, 3] - T[:3, 3])
    c = np.clip((np.trace(Tq[:3, :3].T @ T[:3, :3]) - 1) / 2, -1, 1)
    return dp, np.arccos(c)


CAP = 300.0  # s: only a safety net; every test here is budgeted in iterations (issue 19)


def test_round_trip_random_reachable_poses(kin):
    ik = IKSolver(kin, rng=0)
    rng = np.random.default_rng(0)
    solved = 0
    for _ in range(200):
        T = kin.fk(rng.uniform(kin.lower, kin.upper))
        res = ik.solve(T, seed_q=rng.uniform(kin.lower, kin.upper), max_iterations=4000, timeout=CAP)
        if res.ok:
            solved += 1
            q = res.solutions[0]
            assert np.all(q >= kin.lower) and np.all(q <= kin.upper)
            dp, dr = _pose_error(kin, q, T)
            assert dp < 1e-5 and dr < 1e-5
    assert solved >= 199  # an iteration budget: CPU contention cannot fail the test


def test_pose_target_and_multiple_distinct_solutions(kin):
    ik = IKSolver(kin, rng=1)
    target = Pose.from_matrix(kin.fk(np.array([0.3, 0.2, -0.1, -2.0, 0.1, 2.0, 0.5])))
    res = ik.solve(target, max_iterations=8000, timeout=CAP, max_solutions=3)
    assert res.status is IKStatus.SUCCESS and len(res.solutions) == 3
    for i, a in enumerate(res.solutions):
        assert _pose_error(kin, a, target.matrix())[0] < 1e-5
        for b in res.solutions[i + 1:]:
            assert np.abs(a - b).max() > 0.05


def test_unreachable_pose_fails_within_its_iteration_budget(kin):
    ik = IKSolver(kin, rng=2)
    T = np.eye(4)
    T[:3, 3] = (2.0, 0.0, 0.5)  # 2 m away: beyond the Panda's reach
    res = ik.solve(T, max_iterations=400, timeout=CAP)
    assert res.status is IKStatus.FAILED and res.iterations == 400  # stops at the budget, not later


def test_collision_aware_rejects_colliding_solutions(kin):
    q_ref = np.array([0.0, 0.2, 0.0, -2.0, 0.0, 2.2, 0.785])
    T = kin.fk(q_ref)
    # a checker that forbids elbow-up (joint 2 > 0) solutions: the search must go on past them
    ik = IKSolver(kin, collision_checker=lambda Q: Q[:, 1] > 0.0, rng=3)
    res = ik.solve(T, seed_q=q_ref, max_iterations=8000, timeout=CAP)
    assert res.ok and res.solutions[0][1] <= 0.0
    assert res.rejected_in_collision >= 1
    everything = IKSolver(kin, collision_checker=lambda Q: np.ones(len(Q), bool), rng=4)
    assert everything.solve(T, seed_q=q_ref, max_iterations=400, timeout=CAP).status is IKStatus.IN_COLLISION


def test_bad_input(kin):
    ik = IKSolver(kin)
    with pytest.raises(InvalidInputError):
        ik.solve(np.full((4, 4), np.nan))
    with pytest.raises(InvalidInputError):
        ik.solve(np.eye(4), timeout=0.0)


def test_an_iteration_budget_finds_the_same_solutions_however_slow_the_machine(kin):
    """max_iterations bounds the search, not the clock: a solver slowed down (here by a checker that
    sleeps, as a loaded CPU would) finds exactly what the fast one finds from the same rng."""
    import time

    T = kin.fk(np.array([0.3, 0.4, -0.2, -2.1, 0.1, 2.4, 0.5]))

    def slow(Q):
        time.sleep(0.002)  # a slow checker (work, not synchronisation): budgets in iterations hold
        return np.zeros(len(Q), bool)

    results = [IKSolver(kin, collision_checker=c, rng=9).solve(T, timeout=30.0, max_solutions=50,
                                                               max_iterations=120)
               for c in (lambda Q: np.zeros(len(Q), bool), slow)]
    for r in results:
        assert r.ok and r.iterations == 120
    assert len(results[0].solutions) == len(results[1].solutions) >= 2
    for a, b in zip(*(r.solutions for r in results)):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(InvalidInputError):
        IKSolver(kin).solve(T, max_iterations=0)

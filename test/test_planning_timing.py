"""ruckig time parameterization: exactly on the joint-space segments, within V/A/J limits."""
import numpy as np
import pytest

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.planning.timing import time_parameterize
from skillgen_ros.core.robot import A_MAX, V_MAX


def _segment_distance(x, P):
    return min(np.linalg.norm(a + np.clip((x - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1) * (b - a) - x)
               for a, b in zip(P[:-1], P[1:]))


@pytest.mark.parametrize("scale", [1.0, 0.3])
def test_stays_on_segments_within_limits(scale):
    rng = np.random.default_rng(0)
    P = rng.uniform(-1.5, 1.5, size=(5, 7))
    P[:, 3] = -np.abs(P[:, 3])
    P[2, 1] = P[1, 1]  # a segment where one joint does not move
    tr = time_parameterize(P, dt=0.01, scale=scale)
    assert max(_segment_distance(x, P) for x in tr.positions) < 1e-12
    assert np.all(np.abs(tr.velocities) <= V_MAX * scale + 1e-9)
    assert np.all(np.abs(tr.accelerations) <= A_MAX * scale + 1e-9)
    assert np.all(np.diff(tr.times) > 0)
    np.testing.assert_allclose(tr.positions[[0, -1]], P[[0, -1]])
    for wp in P:  # every waypoint is reached, at rest
        k = np.argmin(np.linalg.norm(tr.positions - wp, axis=1))
        assert np.linalg.norm(tr.positions[k] - wp) < 1e-12 and np.abs(tr.velocities[k]).max() < 1e-9
    # at least one joint reaches its limit on the long segments: the timing is not padded
    assert np.abs(tr.velocities / (V_MAX * scale)).max() > 0.99


def test_bad_paths_rejected():
    with pytest.raises(InvalidInputError):
        time_parameterize(np.full((2, 7), np.nan))
    with pytest.raises(InvalidInputError):
        time_parameterize(np.zeros((2, 6)))
    one = time_parameterize(np.zeros((1, 7)))
    assert one.duration == 0.0 and len(one.positions) == 1

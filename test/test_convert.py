"""Round trips of the message <-> core conversions in skillgen_ros/nodes/convert.py."""
import numpy as np
from scipy.spatial.transform import Rotation

from skillgen_ros.core.geometry import Pose
from skillgen_ros.nodes import convert


def test_pose_round_trip():
    p = Pose(np.array([0.1, -0.2, 0.3]), Rotation.from_euler("xyz", [0.1, 0.2, 0.3]).as_quat())
    q = convert.pose_from_msg(convert.pose_to_msg(p))
    assert np.allclose(p.position, q.position) and np.allclose(p.quaternion, q.quaternion)


def test_cloud_round_trip_with_and_without_colour():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(100, 3)).astype(np.float32)
    back = convert.cloud_to_points(convert.points_to_cloud(pts, "world"))
    assert np.array_equal(back, pts.astype(np.float64))
    rgb = rng.integers(0, 255, size=(100, 3))
    msg = convert.points_to_cloud(pts, "world", rgb=rgb)
    assert msg.point_step == 16
    assert np.array_equal(convert.cloud_to_points(msg), pts.astype(np.float64))


def test_organized_cloud_keeps_nans_and_shape():
    pts = np.full((4 * 5, 3), np.nan, dtype=np.float32)
    pts[3] = [1, 2, 3]
    msg = convert.points_to_cloud(pts, "cam", organized_shape=(4, 5))
    assert (msg.height, msg.width) == (4, 5) and not msg.is_dense
    back = convert.cloud_to_points(msg)
    assert back.shape == (20, 3) and np.array_equal(back[3], [1, 2, 3]) and np.isnan(back[0]).all()


def test_trajectory_round_trip():
    names = [f"j{i}" for i in range(7)]
    t = np.array([0.0, 0.5, 1.25])
    q = np.arange(21, dtype=float).reshape(3, 7) / 10
    v = q * 0.5
    n2, t2, q2, v2 = convert.trajectory_from_msg(convert.trajectory_to_msg(names, t, q, v))
    assert n2 == names and np.allclose(t2, t) and np.allclose(q2, q) and np.allclose(v2, v)


def test_seconds_to_duration_carries_rounded_nanoseconds_into_seconds():
    # 1.9999999999 s rounds to 2_000_000_000 ns: that is sec=2, nanosec=0, never nanosec=10**9.
    for t, (sec, nsec) in {1.9999999999: (2, 0), 0.9999999996: (1, 0), 2.5: (2, 500_000_000),
                           0.0: (0, 0), 3.000000001: (3, 1), 1e-10: (0, 0)}.items():
        d = convert.seconds_to_duration(t)
        assert (d.sec, d.nanosec) == (sec, nsec), t
        assert 0 <= d.nanosec < 1_000_000_000
    for t in np.linspace(0.0, 5.0, 1001):
        d = convert.seconds_to_duration(float(t))
        assert 0 <= d.nanosec < 1_000_000_000
        assert abs(convert.duration_to_seconds(d) - t) <= 1e-9

"""Why cloud.py has its own plane RANSAC (its docstring): open3d's segment_plane takes the plane with
the most inliers, so a wall seen by more points than the table wins; ours keeps to level planes."""
import numpy as np
import open3d as o3d

from skillgen_ros.core.perception import cloud


def test_a_big_wall_wins_open3d_but_not_ours():
    rng = np.random.default_rng(0)
    table = np.column_stack([rng.uniform(0.3, 0.8, 3000), rng.uniform(-0.3, 0.3, 3000), np.full(3000, -0.09)])
    wall = np.column_stack([np.full(6000, 0.9), rng.uniform(-0.3, 0.3, 6000), rng.uniform(-0.09, 0.6, 6000)])
    pts = np.concatenate([table, wall]) + rng.normal(0, 0.001, (9000, 3))
    o3d.utility.random.seed(0)
    model, _ = cloud.to_o3d(pts).segment_plane(0.005, 3, 500)
    assert abs(model[2]) < 0.2, "open3d picks the wall (normal along x)"
    plane = cloud.fit_table_plane(pts, 0.005)
    assert plane is not None and plane.normal[2] > 0.99 and abs(plane.offset - 0.09) < 0.003

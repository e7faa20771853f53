"""mock_driver node: the kinematic MockWorld behind the same driver interface as sim_driver.

For fast graph tests only (never the main job, benchmarks or end-to-end tests): the EE follows
targets exactly, trajectories complete at once, objects stay where reset_scene put them, camera
points are mesh-surface samples. No pybullet import, so it starts in well under a second.
"""
from __future__ import annotations

import sys

from skillgen_ros.nodes.runtime import run_node


def make_world(param):
    from skillgen_ros.core.sim.mock import MockWorld
    from skillgen_ros.nodes.driver_cameras import camera_configs

    return MockWorld(float(param("control_hz")), camera_configs(param))


def mock_driver():
    from skillgen_ros.nodes.driver_base import DriverNode

    return DriverNode("mock_driver", make_world)


def main(args=None) -> int:
    return run_node(mock_driver, args)


if __name__ == "__main__":
    sys.exit(main())

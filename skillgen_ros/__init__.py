"""skillgen_ros: SkillMimicGen demonstration generation on ROS 2 Jazzy.

`skillgen_ros.core` holds the algorithms and imports no rclpy; `skillgen_ros.nodes` holds the thin
ROS shells; `skillgen_ros.cli` is the `skillgen` command line for pip-only machines.
"""
__version__ = "0.1.0"

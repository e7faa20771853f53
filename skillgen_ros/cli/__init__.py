"""The `skillgen` command line: what `ros2 run`, `ros2 launch` and `ros2 bag` do, for pip-only machines."""

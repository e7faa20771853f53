"""Pure core: algorithms with no rclpy import, unit-tested directly."""

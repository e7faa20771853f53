"""What Foxglove needs to draw a session as a 3D scene: /tf from joint states and object poses,
the robot model, object models as markers (docs/foxglove.md). Pure: no rclpy; messages are
CDR-encoded with rosbags' typestore, so tf2_msgs (not on PyPI) needs no Python package."""

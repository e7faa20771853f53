"""Thin ROS 2 shells: parameters, interfaces, callbacks that call skillgen_ros.core, conversions."""

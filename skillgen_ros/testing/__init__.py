"""skillgen_ros.testing: a pytest plugin for testing your own code against skillgen_ros nodes.

Registered through the `pytest11` entry point (name `skillgen_ros.testing`), so it is active
wherever skillgen_ros is installed; `-p no:skillgen_ros.testing` turns it off. Fixtures
(docs/testing.md):

- `ros_domain`: a ROS_DOMAIN_ID no other test on the machine holds, loopback-only discovery.
- `ros_node`: an rclpy node on that domain with an executor spinning in the background.
- `graph(name, **node_parameters)`: launches a graphs.yaml graph, waits until its nodes answer.
- `mock_driver` / `sim_driver`: the robot drivers, ready (services, actions and topics answer),
  with their interface's names and the newest joint_states / ee_pose.
- marker `ros_keep_logs` / option `--ros-keep-logs`: a failing test keeps its node logs and bags
  in tmp_path/ros. A failing test's report always shows the end of each node's log.

Every node process is stopped after its test, pass or fail, and dies with pytest if pytest is
killed (testing/processes.py).
"""
from skillgen_ros.testing.domains import DomainLease, NoFreeDomainError, acquire_domain
from skillgen_ros.testing.plugin import (graph, mock_driver, pytest_addoption, pytest_configure,
                                         pytest_runtest_makereport, ros_artifacts, ros_domain, ros_node, sim_driver)
from skillgen_ros.testing.processes import RosProcess, node_command, process_env
from skillgen_ros.testing.wait import wait_for

__all__ = ["DomainLease", "NoFreeDomainError", "RosProcess", "acquire_domain", "graph", "mock_driver", "node_command",
           "process_env", "ros_artifacts", "ros_domain", "ros_node", "sim_driver", "wait_for"]

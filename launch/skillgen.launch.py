"""Launch a named skillgen_ros graph on a full ROS 2 install:

    ros2 launch skillgen_ros skillgen.launch.py graph:=datagen

The graph comes from skillgen_ros/graphs.yaml, the same declaration `skillgen launch` reads.
"""
import os

import yaml
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from skillgen_ros.graphs import load_graph, processes
from skillgen_ros.rosenv import launch_environment


def _env() -> dict:
    """Loopback-only discovery and one math thread per node, unless the user set them (issue 19:
    this file once forced LOCALHOST over a user's ROS_AUTOMATIC_DISCOVERY_RANGE)."""
    return launch_environment(os.environ)


def _nodes(context, *args, **kwargs):
    graph = LaunchConfiguration("graph").perform(context)
    nodes = []
    graph_nodes = load_graph(graph)
    for n in graph_nodes:
        if n.container is not None:
            continue
        nodes.append(Node(package="skillgen_ros", executable=n.exe, name=n.name, arguments=list(n.args),
                          parameters=([n.params_file] if n.params_file else [])
                          + ([{k: yaml.safe_load(v) for k, v in n.parameters}] if n.parameters else []),
                          output="screen", additional_env=_env()))
    for p in processes(graph_nodes):  # composed nodes: the container's arguments carry their parameters
        if p.exe == "container":
            nodes.append(Node(package="skillgen_ros", executable="container", arguments=list(p.args),
                              output="screen", additional_env=_env()))
    return nodes


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument("graph", default_value="datagen", description="graph name in graphs.yaml"),
        OpaqueFunction(function=_nodes),
    ])

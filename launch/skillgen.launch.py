"""Launch a named skillgen_ros graph on a full ROS 2 install:

    ros2 launch skillgen_ros skillgen.launch.py graph:=datagen

The graph comes from skillgen_ros/graphs.yaml, the same declaration `skillgen launch` reads.
"""
import yaml
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from skillgen_ros.graphs import load_graph


def _nodes(context, *args, **kwargs):
    graph = LaunchConfiguration("graph").perform(context)
    nodes = []
    for n in load_graph(graph):
        nodes.append(Node(package="skillgen_ros", executable=n.exe, name=n.name, arguments=list(n.args),
                          parameters=([n.params_file] if n.params_file else [])
                          + ([{k: yaml.safe_load(v) for k, v in n.parameters}] if n.parameters else []),
                          output="screen",
                          additional_env={"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}))
    return nodes


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument("graph", default_value="datagen", description="graph name in graphs.yaml"),
        OpaqueFunction(function=_nodes),
    ])

"""The package is a correct ament_python package and every executable resolves like `ros2 run`."""
import os
import sys
from pathlib import Path

import pytest
import yaml
from ament_index_python.packages import get_package_prefix, get_package_share_directory
from catkin_pkg.package import parse_package

from skillgen_ros.graphs import COMPOSABLE, NodeLaunch, graph_names, load_graph, node_executables, processes

REPO = Path(__file__).resolve().parents[1]
EXPECTED = {"sim_driver", "mock_driver", "perception", "planner", "skill_replay", "datagen", "hsp",
            "recorder", "player", "teleop"}


def test_every_node_executable_is_declared():
    assert EXPECTED | {"container"} <= set(node_executables())
    assert set(COMPOSABLE) <= EXPECTED


def test_container_groups_become_one_process_with_node_targeted_args():
    nodes = [NodeLaunch("sim_driver", "/p/sim_driver.yaml", parameters=(("camera_hz", "0.0"),), container="loop"),
             NodeLaunch("planner", "/p/planner.yaml", parameters=(("dt", "0.01"),)),
             NodeLaunch("skill_replay", None, name="replay", container="loop")]
    procs = processes(nodes)
    assert [p.exe for p in procs] == ["container", "planner"]  # the container where its first node is
    c = procs[0].args
    assert c[:3] == ("sim_driver", "skill_replay", "--ros-args") and c.count("--ros-args") == 1
    assert "sim_driver:camera_hz:=0.0" in c and "skill_replay:__node:=replay" in c and "/p/sim_driver.yaml" in c
    assert procs[1].args == ("--ros-args", "--params-file", "/p/planner.yaml", "-p", "dt:=0.01")
    datagen = {p.exe: p for p in processes(load_graph("datagen"))}
    assert datagen["container"].args[:2] == ("sim_driver", "skill_replay") and "sim_driver" not in datagen


def test_only_composable_nodes_share_a_container(tmp_path, monkeypatch):
    from skillgen_ros.graphs import UnknownNodeError

    bad = tmp_path / "graphs.yaml"
    bad.write_text("graphs:\n  g:\n    nodes:\n      - exe: teleop\n        container: c\n")
    monkeypatch.setenv("SKILLGEN_GRAPHS", str(bad))
    with pytest.raises(UnknownNodeError, match="only"):
        load_graph("g")


@pytest.mark.parametrize("exe", sorted(EXPECTED))
def test_ament_index_resolves_executable(exe):
    # What `ros2 run skillgen_ros <exe>` does: prefix from AMENT_PREFIX_PATH, then lib/<pkg>/<exe>.
    prefix = Path(get_package_prefix("skillgen_ros"))
    path = prefix / "lib" / "skillgen_ros" / exe
    assert path.exists() and os.access(path, os.X_OK), path
    assert (Path(sys.prefix) / "bin" / exe).exists()


def test_interfaces_package_in_ament_index():
    assert Path(get_package_prefix("skillgen_interfaces")).is_dir()
    share = Path(get_package_share_directory("skillgen_interfaces"))
    assert (share / "msg" / "OscTarget.msg").exists()


def test_package_xml_is_format_3_ament_python():
    pkg = parse_package(str(REPO / "package.xml"))
    assert pkg.package_format == 3
    assert pkg.get_build_type() == "ament_python"
    assert "rclpy" in {d.name for d in pkg.exec_depends}
    iface = parse_package(str(REPO / "msg_defs" / "package.xml"))
    assert iface.name == "skillgen_interfaces" and iface.get_build_type() == "ament_cmake"


def test_standard_messages_are_not_redefined():
    names = {p.stem for p in (REPO / "msg_defs" / "msg").glob("*.msg")}
    assert not names & {"PoseStamped", "Pose", "JointState", "PointCloud2", "JointTrajectory", "Image"}


@pytest.mark.parametrize("exe", sorted(EXPECTED))
def test_params_file_per_node_in_ros_form(exe):
    doc = yaml.safe_load((REPO / "params" / f"{exe}.yaml").read_text())
    assert list(doc) == [exe] and "ros__parameters" in doc[exe]


def test_graphs_resolve_to_known_nodes():
    for g in graph_names():
        nodes = load_graph(g)
        assert nodes and all(n.exe in EXPECTED for n in nodes)


def test_launch_file_reads_the_same_graphs():
    text = (REPO / "launch" / "skillgen.launch.py").read_text()
    assert "load_graph" in text  # the launch file and `skillgen launch` share one declaration

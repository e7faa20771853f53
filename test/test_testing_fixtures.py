"""The plugin's graph and driver fixtures in our own suite: a user's graph file, names and
namespaces, a node that dies while starting, bad overrides, the sim driver's initial scene."""
from __future__ import annotations

import pytest

from skillgen_ros.graphs import UnknownNodeError
from skillgen_ros.testing import wait_for
from skillgen_ros.testing.readiness import NotReadyError

USER_GRAPHS = """
graphs:
  arm:
    description: a renamed mock driver (a user's graph file)
    nodes:
      - exe: mock_driver
        name: arm
        parameters: {camera_hz: 0.0}
"""


def test_graph_from_a_user_file_under_a_namespace(graph, ros_node, tmp_path):
    graphs_file = tmp_path / "graphs.yaml"
    graphs_file.write_text(USER_GRAPHS)
    g = graph("arm", graphs_file=graphs_file, namespace="/w1", arm={"lockstep_timeout_s": 0.1})
    assert g.node_names == ["/w1/arm"] and g.process("arm") is g.process("mock_driver")
    assert wait_for(lambda: ros_node.count_publishers("/w1/joint_states") == 1, 10)
    assert ros_node.count_publishers("/joint_states") == 0
    assert "[w1.arm]: mock_driver up" in g.process("arm").output()
    codes = g.stop()
    assert codes == {"mock_driver": 0}, codes  # SIGINT: a clean stop


def test_a_node_that_dies_while_starting_fails_the_setup_with_its_log(graph):
    with pytest.raises(NotReadyError) as e:
        graph("mock", mock_driver={"control_hz": -1.0})
    assert e.value.reason == "NOT_READY" and "exited with code 2" in str(e.value)
    assert "control_hz must be > 0" in str(e.value)  # the end of the node's log


def test_overrides_for_a_node_the_graph_does_not_have_are_refused(graph):
    with pytest.raises(UnknownNodeError) as e:
        graph("mock", planner={"dt": 0.01})
    assert e.value.reason == "UNKNOWN_NODE" and "planner" in str(e.value) and "mock_driver" in str(e.value)


@pytest.mark.mock_driver(namespace="/w2", camera_hz=0.0)
def test_mock_driver_marker_sets_namespace_and_parameters(mock_driver, ros_node):
    assert mock_driver.name == "/w2/mock_driver" and mock_driver.topics["osc_target"] == "/w2/osc_target"
    js = mock_driver.joint_states()
    assert len(js.position) >= 7 and mock_driver.ee_position().shape == (3,)
    assert ros_node.count_publishers("/w2/camera/front/image") == 1 and "cameras ['front', 'wrist']" in mock_driver.output()


@pytest.mark.sim_driver(task="Square", variant="D0", seed=0, cameras=[""])
def test_sim_driver_starts_in_the_requested_scene(sim_driver):
    gt = sim_driver.wait_ground_truth()
    assert sorted(o.id for o in gt.objects) == ["square_nut", "square_peg"]
    r = sim_driver.reset_scene("Square", "D1", 3)
    assert r.success and r.reason_code == "OK"
    assert sim_driver.process.alive


@pytest.mark.parametrize("mock_driver", [{"cameras": ["front"], "lockstep_timeout_s": 0.2}], indirect=True)
def test_mock_driver_takes_parameters_by_indirect_parametrization(mock_driver, ros_node):
    assert "cameras ['front']" in mock_driver.output()
    assert ros_node.count_publishers("/camera/wrist/image") == 0


def test_graph_handle_finds_each_nodes_process_containers_included():
    from skillgen_ros.graphs import graph_names, load_graph, processes
    from skillgen_ros.testing.handles import GraphHandle

    for name in graph_names():
        nodes = load_graph(name)
        launches = processes(nodes)
        h = GraphHandle(name, 0, "", nodes, launches, None)  # ProcessLaunch stands in for the processes
        for n in nodes:
            p = h.process(n.exe)
            assert p.label == n.exe or (n.container and p.label.startswith(f"{n.container} (") and n.exe in p.label)

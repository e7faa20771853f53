"""What the fixtures hand a test: a spinning rclpy node, a launched graph, a driver.

`launch_graph` starts a graphs.yaml graph the way `skillgen launch` does (graphs.processes: one
process per node, containers shared), each process in the test's domain, with its log and rcl
log files and any recorder's bag in the test's artifact directory, and returns once every node
answers (readiness.py).
"""
from __future__ import annotations

import contextlib
import dataclasses
import re
import threading
import time
from pathlib import Path

import numpy as np

from skillgen_ros.graphs import NodeLaunch, UnknownNodeError, _ros_value, load_graph, processes
from skillgen_ros.shm import clean_zombie_files
from skillgen_ros.testing import readiness
from skillgen_ros.testing.processes import RosProcess, node_command, process_env

DRIVER_TOPICS = ("joint_states", "ee_pose", "ee_wrench", "gripper_state", "osc_target", "driver/errors",
                 "sim/ground_truth/object_poses")
DRIVER_SERVICES = ("reset_scene", "task_success", "capture_cameras")
DRIVER_ACTIONS = ("execute_trajectory", "gripper_command")


@contextlib.contextmanager
def spinning_node(domain: int, name: str):
    """An rclpy node in a context of its own on `domain`, its executor spinning in a background
    thread; shut down on exit."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    try:
        node = rclpy.create_node(re.sub(r"\W", "_", name)[:60] or "test_node", context=ctx)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        thread = threading.Thread(target=ex.spin, daemon=True, name=f"spin {node.get_name()}")
        thread.start()
        try:
            yield node
        finally:
            ex.shutdown()
            thread.join(5.0)
            node.destroy_node()
    finally:
        rclpy.shutdown(context=ctx)


def _fq(namespace: str, name: str) -> str:
    return f"{namespace.rstrip('/')}/{name}" if namespace else f"/{name}"


def _process_index(nodes: list[NodeLaunch]) -> list[int]:
    """Each node's process, as graphs.processes orders them (a container where its first node is)."""
    index, containers = [], {}
    for n in nodes:
        if n.container is None:
            index.append(len(set(index)))
        else:
            if n.container not in containers:
                containers[n.container] = len(set(index))
            index.append(containers[n.container])
    return index


class GraphHandle:
    """A running graph: its nodes' names, processes and logs. `stop()` ends every process."""

    def __init__(self, name: str, domain: int, namespace: str, nodes: list[NodeLaunch],
                 procs: list[RosProcess], artifacts: Path):
        self.name, self.domain, self.namespace = name, domain, namespace
        self.nodes = nodes
        self.processes = procs
        self.artifacts = artifacts
        self.node_names = [_fq(namespace, n.name or n.exe) for n in nodes]

    def process(self, node: str) -> RosProcess:
        """The process running `node` (exe or name; a container's process for a node inside one)."""
        for n, i in zip(self.nodes, _process_index(self.nodes)):
            if node in (n.exe, n.name) and i < len(self.processes):
                return self.processes[i]
        raise KeyError(f"graph '{self.name}' has no node '{node}'")

    def output(self) -> str:
        return "\n".join(f"--- {p.label}\n{p.output()}" for p in self.processes)

    def check_alive(self) -> None:
        """NOT_READY naming a node process that has exited, with the end of its log."""
        readiness.check_alive(self.processes)

    def stop(self) -> dict[str, int]:
        """Stop every process (last started first); their exit codes by label."""
        return {p.label: p.stop() for p in reversed(self.processes)}


def _with_overrides(nodes: list[NodeLaunch], overrides: dict[str, dict], bag_dir: Path, graph: str):
    known = {n.name or n.exe for n in nodes} | {n.exe for n in nodes}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise UnknownNodeError(f"graph '{graph}' has no node {', '.join(unknown)}; its nodes: {', '.join(sorted(known))}")
    out = []
    for n in nodes:
        extra = {**overrides.get(n.exe, {}), **overrides.get(n.name or n.exe, {})}
        if n.exe == "recorder" and "output" not in extra and "output" not in dict(n.parameters):
            extra["output"] = str(bag_dir / (n.name or n.exe))  # a failing test's bag is kept with its logs
        params = [(k, v) for k, v in n.parameters if k not in extra]
        params += [(str(k), _ros_value(v)) for k, v in extra.items()]
        out.append(dataclasses.replace(n, parameters=tuple(params)))
    return out


def launch_graph(name: str, domain: int, node, artifacts: Path, *, graphs_file=None, namespace: str = "",
                 timeout: float = 60.0, env: dict | None = None, on_start=None,
                 **node_parameters: dict) -> GraphHandle:
    """Start graph `name` and wait until each of its nodes answers. `node_parameters` maps a node
    (exe or name) to parameter overrides, e.g. mock_driver={"camera_hz": 0.0}."""
    nodes = _with_overrides(load_graph(name, graphs_file=graphs_file), node_parameters, artifacts / "bags", name)
    (artifacts / "bags").mkdir(parents=True, exist_ok=True)
    penv = process_env(domain, artifacts / "ros_log", **(env or {}))
    clean_zombie_files()  # a node killed by an earlier test leaves Fast DDS files behind (skillgen_ros/shm.py)
    procs: list[RosProcess] = []
    handle = GraphHandle(name, domain, namespace, nodes, procs, artifacts)
    try:
        for i, proc in enumerate(processes(nodes)):
            args = [*proc.args, *(["-r", f"__ns:={namespace}"] if namespace else [])]
            label = proc.label
            log = artifacts / f"{i:02d}_{re.sub(r'[^A-Za-z0-9_.-]+', '_', proc.label).strip('_')}.log"
            procs.append(RosProcess(label, [*node_command(proc.exe), *args], penv, log, cwd=artifacts))
            if on_start is not None:  # the plugin reports a failing test's node logs
                on_start(procs[-1])
        end = time.monotonic() + timeout
        for fq in handle.node_names:
            readiness.node_answers(node, fq, end, procs)
    except BaseException:
        handle.stop()
        raise
    return handle


class DriverHandle:
    """A running mock_driver / sim_driver: its interface's names and the newest robot state."""

    def __init__(self, graph: GraphHandle, node, node_name: str, timeout: float):
        from geometry_msgs.msg import PoseStamped
        from sensor_msgs.msg import JointState

        from skillgen_ros.nodes.latest import LatestMessage

        self.graph, self.node = graph, node
        self.domain, self.namespace = graph.domain, graph.namespace
        self.name = _fq(graph.namespace, node_name)
        self.process = graph.process(node_name)
        self.topics = {t: _fq(graph.namespace, t) for t in DRIVER_TOPICS}
        self.services = {s: _fq(graph.namespace, s) for s in DRIVER_SERVICES}
        self.actions = {a: _fq(graph.namespace, a) for a in DRIVER_ACTIONS}
        self._js = LatestMessage(node, JointState, self.topics["joint_states"])
        self._ee = LatestMessage(node, PoseStamped, self.topics["ee_pose"])
        try:
            self._wait_ready(time.monotonic() + timeout)
        except BaseException:
            self.close()
            raise

    def _wait_ready(self, end: float) -> None:
        from skillgen_interfaces.srv import TaskSuccess

        procs = self.graph.processes
        readiness.answered(self.node, TaskSuccess, self.services["task_success"], TaskSuccess.Request, end, procs)
        for action in self.actions.values():
            readiness.action_answers(self.node, action, end, procs)
        readiness.first_message(self._js, end, procs)
        readiness.first_message(self._ee, end, procs)

    def wait_ground_truth(self, timeout: float = 60.0):
        """The (latched) ground-truth object poses of the current scene (sim_driver)."""
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        from skillgen_interfaces.msg import ObjectPoseArray
        from skillgen_ros.nodes.latest import LatestMessage

        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        reader = LatestMessage(self.node, ObjectPoseArray, self.topics["sim/ground_truth/object_poses"], latched)
        try:
            end = time.monotonic() + timeout
            while True:
                msg = readiness.first_message(reader, end, self.graph.processes)
                if msg.objects or time.monotonic() >= end:
                    return msg
                reader.wait_newer(reader.count, max(0.0, end - time.monotonic()))
        finally:
            reader.destroy()

    def joint_states(self, timeout: float = 5.0):
        """The newest sensor_msgs/JointState."""
        return self._js.latest(timeout)

    def ee_pose(self, timeout: float = 5.0):
        """The newest geometry_msgs/PoseStamped of the end effector."""
        return self._ee.latest(timeout)

    def ee_position(self, timeout: float = 5.0) -> np.ndarray:
        p = self.ee_pose(timeout).pose.position
        return np.array([p.x, p.y, p.z])

    def reset_scene(self, task: str, variant: str = "D0", seed: int = 0, timeout: float = 30.0):
        """Call reset_scene (repeated until answered: the same seed is the same scene)."""
        from skillgen_interfaces.srv import ResetScene

        return readiness.answered(self.node, ResetScene, self.services["reset_scene"],
                                  lambda: ResetScene.Request(task=task, variant=variant, seed=seed),
                                  time.monotonic() + timeout, self.graph.processes, each=timeout / 2)

    def output(self) -> str:
        return self.process.output()

    def close(self) -> None:
        self._js.destroy()
        self._ee.destroy()

"""Graph declarations (graphs.yaml): the one source for `skillgen launch` and launch files.

Pure (no rclpy): resolves a named graph to the executables, parameter files and arguments to
start, and raises a clear UNKNOWN_GRAPH / UNKNOWN_NODE error for names that do not exist.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import yaml

from skillgen_ros.core.errors import SkillGenError

PACKAGE = "skillgen_ros"

# Nodes the `container` executable can run together in one process: executable -> module:factory.
COMPOSABLE = {
    "sim_driver": "skillgen_ros.nodes.sim_driver:sim_driver",
    "mock_driver": "skillgen_ros.nodes.mock_driver:mock_driver",
    "skill_replay": "skillgen_ros.nodes.skill_replay:SkillReplayNode",
    "perception": "skillgen_ros.nodes.perception:PerceptionNode",
    "planner": "skillgen_ros.nodes.planner:PlannerNode",
    "datagen": "skillgen_ros.nodes.datagen:DatagenNode",
}


class UnknownGraphError(SkillGenError):
    reason = "UNKNOWN_GRAPH"


class UnknownNodeError(SkillGenError):
    reason = "UNKNOWN_NODE"


@dataclass(frozen=True)
class NodeLaunch:
    exe: str
    params_file: str | None
    name: str | None = None
    args: tuple[str, ...] = field(default_factory=tuple)
    parameters: tuple[tuple[str, str], ...] = field(default_factory=tuple)  # graph-specific overrides
    container: str | None = None  # nodes naming the same container share one process

    def ros_args(self, targeted: bool = False) -> list[str]:
        """--ros-args for this node; `targeted` prefixes parameters and the name remap with the
        node's name, as a container with several nodes needs (`-p sim_driver:camera_hz:=0.0`)."""
        node = f"{self.exe}:" if targeted else ""
        out = ["--ros-args"]
        if self.params_file:
            out += ["--params-file", self.params_file]
        for k, v in self.parameters:
            out += ["-p", f"{node}{k}:={v}"]
        if self.name:
            out += ["-r", f"{node}__node:={self.name}"]
        return out


@dataclass(frozen=True)
class ProcessLaunch:
    """One process to start: a node's own executable, or `container` running several nodes."""
    label: str
    exe: str
    args: tuple[str, ...]


def processes(nodes: list[NodeLaunch]) -> list[ProcessLaunch]:
    """The processes a graph's nodes run in, in order (a container where its first node is)."""
    groups: dict[str, list[NodeLaunch]] = {}
    order: list[NodeLaunch | str] = []
    for n in nodes:
        if n.container is None:
            order.append(n)
        elif n.container not in groups:
            groups[n.container] = [n]
            order.append(n.container)
        else:
            groups[n.container].append(n)
    out = []
    for item in order:
        if isinstance(item, NodeLaunch):
            out.append(ProcessLaunch(item.exe, item.exe, (*item.args, *item.ros_args())))
            continue
        members = groups[item]
        args = [m.exe for m in members] + ["--ros-args"]
        for m in members:
            args += m.ros_args(targeted=True)[1:]
        out.append(ProcessLaunch(f"{item} ({', '.join(m.exe for m in members)})", "container", tuple(args)))
    return out


def executables() -> list[str]:
    """The package's executables, from its installed console_scripts entry points."""
    from importlib.metadata import entry_points

    return sorted(e.name for e in entry_points(group="console_scripts") if e.value.startswith(f"{PACKAGE}."))


def node_executables() -> list[str]:
    return [e for e in executables() if e != "skillgen"]


def params_dir() -> Path:
    """params/ of the source checkout when running from one (edits apply at once), else share/."""
    src = Path(__file__).resolve().parents[1] / "params"
    if src.is_dir():
        return src
    return Path(os.environ.get("SKILLGEN_SHARE", "")) / "params" if os.environ.get("SKILLGEN_SHARE") else _share_dir() / "params"


def _share_dir() -> Path:
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory(PACKAGE))


def load_graphs(extra: str | os.PathLike | None = None) -> dict:
    """The package's graphs.yaml, plus (overriding by name) `extra`, default the file named by
    $SKILLGEN_GRAPHS."""
    text = resources.files(PACKAGE).joinpath("graphs.yaml").read_text()
    graphs = dict(yaml.safe_load(text)["graphs"])
    extra = extra or os.environ.get("SKILLGEN_GRAPHS")
    if extra:
        try:
            graphs.update((yaml.safe_load(Path(extra).read_text()) or {}).get("graphs", {}))
        except (OSError, yaml.YAMLError, AttributeError) as e:
            raise UnknownGraphError(f"cannot read graphs file {extra}: {e}") from e
    return graphs


def graph_names() -> list[str]:
    return sorted(load_graphs())


def load_graph(name: str, params: Path | None = None, graphs_file: str | os.PathLike | None = None) -> list[NodeLaunch]:
    graphs = load_graphs(graphs_file)
    if name not in graphs:
        raise UnknownGraphError(f"no graph named '{name}'; known graphs: {', '.join(sorted(graphs))}")
    known = set(node_executables())
    pdir = params or params_dir()
    out = []
    for entry in graphs[name]["nodes"]:
        exe = entry["exe"]
        if exe not in known:
            raise UnknownNodeError(f"graph '{name}' names node '{exe}', which is not an executable of "
                                   f"{PACKAGE}; known: {', '.join(sorted(known))}")
        pfile = pdir / entry.get("params", f"{exe}.yaml")
        overrides = tuple((str(k), _ros_value(v)) for k, v in (entry.get("parameters") or {}).items())
        container = entry.get("container")
        if container is not None and (exe not in COMPOSABLE or entry.get("args")):
            raise UnknownNodeError(f"graph '{name}' puts '{exe}' in container '{container}', but only "
                                   f"{', '.join(sorted(COMPOSABLE))} can share a process (without args)")
        out.append(NodeLaunch(exe=exe, params_file=str(pfile) if pfile.is_file() else None,
                              name=entry.get("name"), args=tuple(entry.get("args", ())), parameters=overrides,
                              container=str(container) if container is not None else None))
    return out


def _ros_value(v) -> str:
    """A parameter value as `-p name:=value` wants it (YAML flow syntax)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_ros_value(x) for x in v) + "]"
    if isinstance(v, str) and (not v or _yaml_reads(v) != v):  # '' or 'true' must stay strings
        return "'" + v.replace("'", "''") + "'"
    return str(v)


def _yaml_reads(text: str):
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return None

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

    def ros_args(self) -> list[str]:
        out = ["--ros-args"]
        if self.params_file:
            out += ["--params-file", self.params_file]
        for k, v in self.parameters:
            out += ["-p", f"{k}:={v}"]
        if self.name:
            out += ["-r", f"__node:={self.name}"]
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


def load_graphs() -> dict:
    """The package's graphs.yaml, plus (overriding by name) the file named by $SKILLGEN_GRAPHS."""
    text = resources.files(PACKAGE).joinpath("graphs.yaml").read_text()
    graphs = dict(yaml.safe_load(text)["graphs"])
    extra = os.environ.get("SKILLGEN_GRAPHS")
    if extra:
        try:
            graphs.update((yaml.safe_load(Path(extra).read_text()) or {}).get("graphs", {}))
        except (OSError, yaml.YAMLError, AttributeError) as e:
            raise UnknownGraphError(f"cannot read graphs file {extra}: {e}") from e
    return graphs


def graph_names() -> list[str]:
    return sorted(load_graphs())


def load_graph(name: str, params: Path | None = None) -> list[NodeLaunch]:
    graphs = load_graphs()
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
        out.append(NodeLaunch(exe=exe, params_file=str(pfile) if pfile.is_file() else None,
                              name=entry.get("name"), args=tuple(entry.get("args", ())), parameters=overrides))
    return out


def _ros_value(v) -> str:
    """A parameter value as `-p name:=value` wants it (YAML flow syntax)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_ros_value(x) for x in v) + "]"
    return str(v)

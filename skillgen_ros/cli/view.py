"""`skillgen view`: serve the running graph to Foxglove (WebSocket protocol, foxglove-sdk).

    skillgen view [--port 8765] [--host 127.0.0.1] [--no-scene] [--package-path] [--ros-args ...]

Open Foxglove, "Open connection", Foxglove WebSocket, ws://localhost:8765, and import the layout
docs/foxglove/skillgen.json (a generation run) or docs/foxglove/teleop.json (recording a demo:
wrist and front cameras) (docs/foxglove.md). Loopback only unless --host names another
address: the graph's topics would be readable by anyone who reaches that port.
"""
from __future__ import annotations

import argparse
import os
import sys

from skillgen_ros.core.errors import InvalidInputError


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="skillgen view", description=__doc__.split("\n\n")[0])
    p.add_argument("--port", type=int, default=8765, help="WebSocket port (default 8765; 0 picks a free one)")
    p.add_argument("--host", default="127.0.0.1",
                   help="bind address (default 127.0.0.1, loopback; another address exposes the graph)")
    p.add_argument("--no-scene", action="store_true", help="do not synthesize /tf, /robot_description, markers")
    p.add_argument("--package-path", action="store_true",
                   help="print the folder to set as Foxglove desktop's ROS package path (robot meshes in bags), exit")
    p.add_argument("ros_args", nargs=argparse.REMAINDER, help="--ros-args ... for the viewer node (e.g. a namespace)")
    return p


def main(argv: list[str]) -> int:
    ns = _parser().parse_args(argv)
    if ns.package_path:
        from skillgen_ros.core.viz.description import package_path

        print(package_path())
        return 0
    if not 0 <= ns.port <= 65535:
        raise InvalidInputError(f"--port must be 0..65535, got {ns.port}", reason="INVALID_PARAMETER")
    from skillgen_ros import rosenv

    extra = [a for a in ns.ros_args if a != "--ros-args"]
    args = [sys.executable, "-c", "import sys; from skillgen_ros.nodes.entry import viewer; sys.exit(viewer())",
            "--ros-args", "-p", f"port:={ns.port}", "-p", f"host:='{ns.host}'",
            "-p", f"scene:={'false' if ns.no_scene else 'true'}", *extra]
    os.execve(sys.executable, args, rosenv.ros_environment(dict(os.environ)))
    return 0  # not reached

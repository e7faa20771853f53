"""container: several of this package's nodes in one process, on one executor (ROS 2 composition).

    container sim_driver skill_replay --ros-args --params-file params/sim_driver.yaml \\
        --params-file params/skill_replay.yaml -p sim_driver:camera_hz:=0.0

Why: a skill step is one round trip skill_replay -> driver -> skill_replay. Between two processes
each hop is a DDS delivery, a wake-up of the other process and a second Python interpreter on a
shared core; in one process the nodes share a DDS participant (intra-process delivery) and one
executor thread, which cut the datagen graph's time per attempt by about a quarter (bench/datagen,
graph overhead). The nodes keep their names, topics, services, actions and parameters: other
processes cannot tell. This is what rclcpp's component containers and nav2's `use_composition` do.

Node-targeted arguments address one node of the process: `-p sim_driver:camera_hz:=0.0`,
`-r sim_driver:__node:=robot`. The executor is single-threaded when every node asks for one (the
lockstep driver, skill_replay), else multi-threaded. graphs.yaml groups nodes with `container:`.
"""
from __future__ import annotations

import importlib
import sys

from skillgen_ros.graphs import COMPOSABLE
from skillgen_ros.nodes.runtime import run_nodes


def _factory(exe: str):
    module, attr = COMPOSABLE[exe].split(":")
    return getattr(importlib.import_module(module), attr)


def main(args=None) -> int:
    argv = list(sys.argv if args is None else args)
    cut = argv.index("--ros-args") if "--ros-args" in argv else len(argv)
    names = argv[1:cut]
    unknown = [n for n in names if n not in COMPOSABLE]
    if not names or unknown:
        print(f"[container] UNKNOWN_NODE: {unknown or 'no nodes named'}; composable: {', '.join(sorted(COMPOSABLE))}",
              file=sys.stderr, flush=True)
        return 2
    if len(set(names)) != len(names):
        print(f"[container] INVALID_ARGUMENT: a node is named twice in {names}", file=sys.stderr, flush=True)
        return 2
    return run_nodes([_factory(n) for n in names], [argv[0], *argv[cut:]], name="container")


if __name__ == "__main__":
    sys.exit(main())

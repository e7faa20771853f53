"""`skillgen` entry point: run, launch, bag, and the product's commands.

    skillgen run <exe> [--ros-args ...]     like `ros2 run skillgen_ros <exe>`
    skillgen launch <graph> [--respawn] [--verbose] [--log-dir DIR]
                                            like `ros2 launch skillgen_ros skillgen.launch.py graph:=<graph>`
    skillgen bag info <bag>                 like `ros2 bag info`
    skillgen graphs                         list the graphs in graphs.yaml

Errors print one line "REASON: message" and exit 2; no tracebacks for user mistakes.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from skillgen_ros.core.errors import SkillGenError

# Subcommands implemented in their own modules: name -> (module, help). Each module has main(argv) -> int.
DELEGATED = {
    "bag": ("skillgen_ros.cli.bag", "inspect, record and play bags (rosbag2-layout MCAP)"),
    "annotate": ("skillgen_ros.cli.annotate", "propose, override and validate skill annotations of a demo bag"),
    "demos": ("skillgen_ros.cli.demos", "record source demonstrations (scripted demonstrator or teleop)"),
    "generate": ("skillgen_ros.cli.generate", "run a generation through the node graph (the main job)"),
    "dataset": ("skillgen_ros.cli.dataset", "validate, merge or export generated datasets (robomimic next_obs, LeRobot)"),
    "deploy": ("skillgen_ros.cli.deploy", "evaluate a Hybrid Skill Policy checkpoint (rollouts on held-out seeds)"),
    "train": ("skillgen_ros.cli.train", "learn a Hybrid Skill Policy (π, T, I) from a generated dataset"),
    "view": ("skillgen_ros.cli.view", "serve the running graph to Foxglove (ws://127.0.0.1:8765)"),
}


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="skillgen", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="run one node executable")
    r.add_argument("exe")
    r.add_argument("args", nargs=argparse.REMAINDER)
    la = sub.add_parser("launch", help="start a named graph of nodes")
    la.add_argument("graph")
    la.add_argument("ros_args", nargs=argparse.REMAINDER,
                    help="--respawn (restart a node that dies, like launch's respawn=True), --verbose (stream "
                         "every node's output here instead of to logs/<graph>_<UTC time>/<node>.log), "
                         "--log-dir DIR (where the node logs go), then extra --ros-args for every node")
    sub.add_parser("graphs", help="list graphs")
    for name, (_, helptext) in DELEGATED.items():
        d = sub.add_parser(name, help=helptext, add_help=False)
        d.add_argument("rest", nargs=argparse.REMAINDER)
    return p


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] in DELEGATED:  # the subcommand's own parser sees every remaining word
        return _delegate(argv[0], argv[1:])
    ns = _parser().parse_args(argv)
    try:
        if ns.cmd == "run":
            from skillgen_ros.cli.launcher import run

            return run(ns.exe, ns.args)
        if ns.cmd == "launch":
            from skillgen_ros.cli.launcher import launch

            from skillgen_ros.cli.launcher import default_log_dir

            words, log_dir = _take_option(ns.ros_args, "--log-dir")
            extra = [a for a in words if a not in ("--ros-args", "--respawn", "--verbose")]
            verbose = "--verbose" in words
            return launch(ns.graph, extra, respawn="--respawn" in words,
                          log_dir=None if verbose else (log_dir or default_log_dir(ns.graph)))
        if ns.cmd == "graphs":
            from skillgen_ros.graphs import load_graphs

            for name, g in sorted(load_graphs().items()):
                print(f"{name:14s} {' '.join(n['exe'] for n in g['nodes']):60s} {g.get('description', '')}")
            return 0
        return _delegate(ns.cmd, ns.rest)
    except SkillGenError as e:
        print(str(e), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


def _take_option(words: list[str], name: str) -> tuple[list[str], str | None]:
    """Remove `name VALUE` or `name=VALUE` from words; returns (the rest, VALUE or None)."""
    rest, value, k = [], None, 0
    while k < len(words):
        w = words[k]
        if w == name and k + 1 < len(words):
            value, k = words[k + 1], k + 2
            continue
        if w.startswith(name + "="):
            value = w.split("=", 1)[1]
        else:
            rest.append(w)
        k += 1
    return rest, value


def _delegate(cmd: str, rest: list[str]) -> int:
    module, _ = DELEGATED[cmd]
    try:
        mod = importlib.import_module(module)
    except ModuleNotFoundError as e:
        if e.name == module:
            print(f"NOT_IMPLEMENTED: 'skillgen {cmd}' is not available yet", file=sys.stderr)
            return 3
        raise
    try:
        return int(mod.main(rest) or 0)
    except SkillGenError as e:
        print(str(e), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())

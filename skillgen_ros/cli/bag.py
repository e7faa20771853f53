"""`skillgen bag ...`: inspect, record and play rosbag2-layout MCAP bags without ros2cli.

    skillgen bag info <bag> [--json]                      like `ros2 bag info`
    skillgen bag record [-o DIR] [TOPIC ...|--all] [...]   runs the recorder node until Ctrl-C
    skillgen bag play <bag> [--rate R] [--loop] [...]      runs the player node until done
    skillgen bag recover <bag>                            finalize the .mcap files of a killed recording
    skillgen bag reindex <bag> [<bag> ...] [--no-backup]  complete rosbag2 v9 metadata (QoS) of old bags

Bad input prints one line "REASON: message" and exits 2; no tracebacks.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
from pathlib import Path

from skillgen_ros.core.errors import SkillGenError


def _info(ns) -> int:
    from skillgen_ros.core.bag.info import bag_info, format_info

    info = bag_info(ns.bag)
    if ns.json:
        def plain(o):
            if dataclasses.is_dataclass(o):
                return {k: plain(v) for k, v in dataclasses.asdict(o).items()}
            if isinstance(o, dict):
                return {str(k): plain(v) for k, v in o.items()}
            if isinstance(o, (list, tuple)):
                return [plain(v) for v in o]
            return str(o) if isinstance(o, Path) else o
        doc = plain(info)
        doc["duration_ns"] = info.duration_ns
        print(json.dumps(doc, indent=2, default=str))
    else:
        print(format_info(info))
    return 0


def _recover(ns) -> int:
    from skillgen_ros.core.bag.recover import recover_bag

    done = recover_bag(ns.bag)
    for f in done:
        print(f"recovered {f.path} ({f.message_count} messages); original kept as {f.backup.name}")
    if not done:
        print(f"{ns.bag}: every file is already finalized; nothing to do")
    return 0


def _reindex(ns) -> int:
    from skillgen_ros.core.bag.recover import reindex_bag

    for bag in ns.bags:
        r = reindex_bag(bag, keep_backup=not ns.no_backup)
        for f in r.rewritten:
            kept = f"; original kept as {f.backup.name}" if f.backup else ""
            print(f"rewrote {f.path} ({f.message_count} messages, complete QoS){kept}")
        print(f"{r.path}: metadata.yaml {'rewritten' if r.metadata_changed else 'already complete'}")
    return 0


def _exec_node(exe: str, params: list[tuple[str, object]]) -> int:
    """Replace this process with a node executable (same venv), passing -p overrides."""
    from skillgen_ros import rosenv

    path = Path(sys.prefix) / "bin" / exe
    args = [str(path), "--ros-args"]
    default = Path(__file__).resolve().parents[2] / "params" / f"{exe}.yaml"
    if default.is_file():
        args += ["--params-file", str(default)]
    for name, value in params:
        if isinstance(value, bool):
            value = str(value).lower()
        elif isinstance(value, (list, tuple)):
            value = "[" + ",".join(f"'{v}'" for v in value) + "]"
        args += ["-p", f"{name}:={value}"]
    os.execve(str(path), args, rosenv.ros_environment(dict(os.environ)))
    return 0  # not reached


def _record(ns) -> int:
    params: list[tuple[str, object]] = [("autostart", True), ("all_topics", bool(ns.all or not ns.topics))]
    if ns.topics:
        params.append(("topics", ns.topics))
    if ns.output:
        params.append(("output", str(Path(ns.output).resolve())))
    if ns.compression:
        params.append(("compression", ns.compression))
    if ns.max_bag_size:
        params.append(("max_bag_size", int(ns.max_bag_size)))
    return _exec_node("recorder", params)


def _play(ns) -> int:
    from skillgen_ros.core.bag.reader import BagReader, check_installed, playable_topics

    reader = BagReader(ns.bag)  # fail fast, with a reason, before starting ROS
    if ns.topics or not playable_topics(reader)[0]:  # the whole bag skips what is not installed
        check_installed(reader, ns.topics or None)
    params: list[tuple[str, object]] = [("bag", str(Path(ns.bag).resolve())), ("rate", float(ns.rate)),
                                        ("start_offset", float(ns.start_offset)), ("loop", ns.loop),
                                        ("clock", ns.clock), ("exit_when_done", not ns.stay)]
    if ns.topics:
        params.append(("topics", ns.topics))
    if ns.remap:
        params.append(("remap", ns.remap))
    return _exec_node("player", params)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="skillgen bag", description="rosbag2-layout MCAP bags")
    sub = p.add_subparsers(dest="cmd", required=True)
    i = sub.add_parser("info", help="topics, types, counts, duration, size, annotations")
    i.add_argument("bag")
    i.add_argument("--json", action="store_true", help="machine-readable output")
    rc = sub.add_parser("recover", help="finalize truncated .mcap files (killed recording)")
    rc.add_argument("bag")
    ri = sub.add_parser("reindex", help="regenerate metadata.yaml (complete v9 QoS) from the .mcap files")
    ri.add_argument("bags", nargs="+")
    ri.add_argument("--no-backup", action="store_true", help="do not keep rewritten .mcap files as .orig")
    r = sub.add_parser("record", help="record topics (Ctrl-C finalizes the bag)")
    r.add_argument("topics", nargs="*")
    r.add_argument("-a", "--all", action="store_true", help="record every discovered topic")
    r.add_argument("-o", "--output", help="bag directory to create")
    r.add_argument("--compression", choices=["zstd", "lz4", "none"])
    r.add_argument("--max-bag-size", type=int, help="split files past this many bytes")
    pl = sub.add_parser("play", help="replay a bag dir or .mcap with original timing")
    pl.add_argument("bag")
    pl.add_argument("-r", "--rate", type=float, default=1.0)
    pl.add_argument("--start-offset", type=float, default=0.0, help="seconds into the bag")
    pl.add_argument("-l", "--loop", action="store_true")
    pl.add_argument("--clock", action="store_true", help="publish /clock")
    pl.add_argument("--topics", nargs="*", default=[])
    pl.add_argument("--remap", nargs="*", default=[], help="old:=new pairs")
    pl.add_argument("--stay", action="store_true", help="keep running when done")
    return p


def main(argv: list[str]) -> int:
    ns = _parser().parse_args(argv)
    try:
        return {"info": _info, "record": _record, "play": _play, "recover": _recover,
                "reindex": _reindex}[ns.cmd](ns)
    except SkillGenError as e:
        print(str(e), file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

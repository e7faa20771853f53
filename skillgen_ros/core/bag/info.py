"""`bag info`: what a bag holds, in the shape of `ros2 bag info`, plus skill annotations.

Annotations may live in the bag as an MCAP metadata record named `skillgen_annotations` or
beside it as `annotations.yaml` in the bag directory; both are shown when present.
"""
from __future__ import annotations

import datetime as dt
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import yaml

from skillgen_ros.core.bag.reader import BagReader, McapFileInfo, message_class
from skillgen_ros.core.bag.writer import ANNOTATIONS_RECORD
from skillgen_ros.core.errors import BagError

SIDECAR_ANNOTATIONS = "annotations.yaml"


@dataclass(frozen=True)
class TopicInfo:
    name: str
    type: str
    message_count: int
    serialization_format: str
    reliability: str          # of the first recorded publisher QoS, '' when unknown
    installed: bool           # whether this machine can decode/replay the type


@dataclass(frozen=True)
class BagInfo:
    path: Path
    storage: str
    ros_distro: str
    files: tuple[McapFileInfo, ...]
    topics: tuple[TopicInfo, ...]
    message_count: int
    start_ns: int
    end_ns: int
    size_bytes: int
    compression: tuple[str, ...]
    truncated: bool
    warnings: tuple[str, ...]
    annotations_record: Mapping[str, str] | None
    annotations_sidecar: Any

    @property
    def duration_ns(self) -> int:
        return max(0, self.end_ns - self.start_ns)


def _installed(type_name: str) -> bool:
    try:
        message_class(type_name)
        return True
    except BagError:
        return False


def bag_info(path: str | os.PathLike) -> BagInfo:
    """Summarize a bag directory or bare .mcap; BagError for anything unreadable."""
    reader = BagReader(path)
    warnings = list(reader.warnings)
    sidecar = None
    side = reader.path / SIDECAR_ANNOTATIONS if reader.path.is_dir() else None
    if side is not None and side.is_file():
        try:
            sidecar = yaml.safe_load(side.read_text())
        except yaml.YAMLError as e:
            warnings.append(f"{side} is not valid YAML: {e}")
    meta = reader.bag_metadata or {}
    topics = tuple(
        TopicInfo(name=t.name, type=t.type, message_count=t.message_count,
                  serialization_format=t.serialization_format,
                  reliability=str(t.qos_profiles[0].get("reliability", "")) if t.qos_profiles else "",
                  installed=_installed(t.type))
        for t in sorted(reader.topics.values(), key=lambda t: t.name))
    size = sum(f.size_bytes for f in reader.files)
    if reader.path.is_dir():
        size = sum(p.stat().st_size for p in reader.path.iterdir() if p.is_file())
    return BagInfo(
        path=reader.path, storage="mcap", ros_distro=str(meta.get("ros_distro", "") or ""),
        files=reader.files, topics=topics, message_count=reader.message_count,
        start_ns=reader.start_ns, end_ns=reader.end_ns, size_bytes=size,
        compression=tuple(sorted({c or "none" for f in reader.files for c in f.compression})),
        truncated=reader.truncated, warnings=tuple(warnings),
        annotations_record=reader.metadata_records.get(ANNOTATIONS_RECORD),
        annotations_sidecar=sidecar)


def _size(n: int) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.1f} {unit}" if unit != "B" else f"{n} B"
        n /= 1024
    return f"{n} B"


def _stamp(ns: int) -> str:
    t = dt.datetime.fromtimestamp(ns / 1e9, tz=dt.timezone.utc)
    return f"{t.strftime('%b %d %Y %H:%M:%S')}.{ns % 1_000_000_000:09d} UTC ({ns // 10**9}.{ns % 10**9:09d})"


def _short(value: Any, width: int = 100) -> str:
    text = value if isinstance(value, str) else yaml.safe_dump(value, default_flow_style=True).strip()
    text = " ".join(text.split())
    return text if len(text) <= width else text[: width - 3] + "..."


def format_info(info: BagInfo) -> str:
    """Human-readable summary laid out like `ros2 bag info`."""
    pad = " " * 19
    lines = []
    names = [f.path.name + ("  (TRUNCATED)" if f.truncated else "") for f in info.files]
    lines.append(f"{'Files:':<19}{names[0]}")
    lines += [pad + n for n in names[1:]]
    lines.append(f"{'Bag size:':<19}{_size(info.size_bytes)}")
    lines.append(f"{'Storage id:':<19}{info.storage}")
    if info.ros_distro:
        lines.append(f"{'ROS Distro:':<19}{info.ros_distro}")
    lines.append(f"{'Compression:':<19}{', '.join(info.compression) or 'none'} (mcap chunks)")
    lines.append(f"{'Duration:':<19}{info.duration_ns / 1e9:.9f}s")
    if info.message_count:
        lines.append(f"{'Start:':<19}{_stamp(info.start_ns)}")
        lines.append(f"{'End:':<19}{_stamp(info.end_ns)}")
    lines.append(f"{'Messages:':<19}{info.message_count}")
    label = "Topic information:"
    if not info.topics:
        lines.append(f"{label:<19}(none)")
    for i, t in enumerate(info.topics):
        extra = f" | QoS: {t.reliability}" if t.reliability else ""
        missing = " | TYPE NOT INSTALLED" if not t.installed else ""
        lines.append(f"{label if i == 0 else '':<19}Topic: {t.name} | Type: {t.type} | Count: "
                     f"{t.message_count} | Serialization Format: {t.serialization_format}{extra}{missing}")
    if info.annotations_record is not None:
        lines.append(f"{'Annotations:':<19}MCAP metadata record '{ANNOTATIONS_RECORD}'")
        lines += [f"{pad}  {k}: {_short(v)}" for k, v in info.annotations_record.items()]
    if info.annotations_sidecar is not None:
        lines.append(f"{'Annotations:':<19}sidecar {SIDECAR_ANNOTATIONS}")
        side = info.annotations_sidecar
        items = side.items() if isinstance(side, dict) else [("-", side)]
        lines += [f"{pad}  {k}: {_short(v)}" for k, v in items]
    for w in info.warnings:
        lines.append(f"{'Warning:':<19}{w}")
    return "\n".join(lines)

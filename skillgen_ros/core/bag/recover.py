"""Repair bags so that every MCAP tool (rosbags, Foxglove, ros2 bag) opens them.

`recover_bag`: a SIGKILLed recorder leaves .mcap files without summary and footer. BagReader
already reads them up to the last complete chunk; recovery makes that permanent: each truncated
file is rewritten as a finalized MCAP holding exactly those messages (same schemas, channels,
metadata records and chunk compression), the original is kept beside it as
`<name>.mcap.truncated`, and metadata.yaml is regenerated from the files.

`reindex_bag` (`skillgen bag reindex`): for bags written by older versions (the first shipped
demos had QoS profiles without deadline, lifespan, liveliness, ... which rosbag2 and rosbags
refuse). metadata.yaml is regenerated from the MCAP files with complete rosbag2 v9 QoS profiles,
and a file whose channels carry incomplete QoS, or that has no footer, is rewritten the same way
(the original kept as `<name>.mcap.orig` unless keep_backup=False). Messages are copied byte for
byte; a bag that is already complete is left untouched.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping

import yaml
from mcap.records import Channel
from mcap.writer import CompressionType, Writer

from skillgen_ros.core.bag.qos import complete_profiles, missing_keys
from skillgen_ros.core.bag.reader import BagReader
from skillgen_ros.core.bag.scan import FileScan, stream_records
from skillgen_ros.core.bag.writer import (METADATA_FILE, BagSummary, Compression, FileStats, TopicSpec,
                                          write_metadata)
from skillgen_ros.core.errors import BagError

_BY_NAME = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "": CompressionType.NONE}


@dataclass(frozen=True)
class RecoveredFile:
    path: Path
    backup: Path | None
    message_count: int


@dataclass(frozen=True)
class ReindexResult:
    path: Path
    rewritten: tuple[RecoveredFile, ...]     # .mcap files rewritten (truncated or incomplete QoS)
    metadata_changed: bool                  # metadata.yaml was (re)written


def _same_meta(channel: Channel) -> dict:
    return dict(channel.metadata)


def _rewrite(src: Path, dst: Path, channel_meta: Callable[[Channel], dict] = _same_meta) -> int:
    """Copy src's complete records into a new finalized MCAP at dst; returns messages written."""
    scan = FileScan()
    count = 0
    with open(dst, "xb") as out:
        writer: Writer | None = None
        schema_ids: dict[int, int] = {}
        channel_ids: dict[int, int] = {}
        for channel, msg in stream_records(src, scan):
            if writer is None:
                kind = next(iter(sorted(scan.compression)), "zstd")
                writer = Writer(out, compression=_BY_NAME.get(kind, CompressionType.ZSTD))
                writer.start(profile="ros2", library=scan.library or "skillgen_ros (recovered)")
            if channel.id not in channel_ids:
                schema = scan.schemas.get(channel.schema_id)
                if schema is not None and schema.id not in schema_ids:
                    schema_ids[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
                channel_ids[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schema_ids.get(channel.schema_id, 0),
                    channel_meta(channel))
            writer.add_message(channel_ids[channel.id], log_time=msg.log_time, publish_time=msg.publish_time,
                               data=msg.data, sequence=msg.sequence)
            count += 1
        if writer is None:
            writer = Writer(out)
            writer.start(profile="ros2", library="skillgen_ros (recovered)")
        for name, data in scan.metadata.items():
            writer.add_metadata(name, data)
        writer.finish()
        out.flush()
        os.fsync(out.fileno())
    return count


def _replace_file(path: Path, backup: Path | None, channel_meta=_same_meta) -> RecoveredFile:
    if backup is not None and backup.exists():
        raise BagError(f"{backup} already exists; move it away before repairing again", "BAG_EXISTS")
    tmp = path.with_name(path.name + ".repairing")
    tmp.unlink(missing_ok=True)
    n = _rewrite(path, tmp, channel_meta)
    if backup is not None:
        os.replace(path, backup)
    os.replace(tmp, path)
    return RecoveredFile(path, backup, n)


def _old_custom_data(bag_dir: Path) -> dict:
    try:
        doc = yaml.safe_load((bag_dir / METADATA_FILE).read_text())
        custom = doc["rosbag2_bagfile_information"].get("custom_data") or {}
        return {str(k): str(v) for k, v in custom.items()} if isinstance(custom, Mapping) else {}
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError):
        return {}


def _write_fresh_metadata(bag_dir: Path) -> None:
    """metadata.yaml from what the .mcap files hold (QoS completed; custom_data kept)."""
    fresh = BagReader(bag_dir)
    files = tuple(FileStats(x.path.name, x.start_ns, x.end_ns, x.message_count) for x in fresh.files)
    counted = [x for x in files if x.message_count]
    summary = BagSummary(
        path=fresh.path, files=files,
        topic_counts={t.name: t.message_count for t in fresh.topics.values()},
        message_count=fresh.message_count,
        start_ns=min((x.start_ns for x in counted), default=0),
        end_ns=max((x.end_ns for x in counted), default=0))
    try:
        topics = [TopicSpec(t.name, t.type, complete_profiles(t.qos_profiles), t.serialization_format)
                  for t in fresh.topics.values()]
    except BagError as e:
        raise BagError(f"{bag_dir}: {e.args[0]}", e.reason) from None
    kinds = {c for x in fresh.files for c in x.compression}
    compression = Compression.parse(next(iter(sorted(kinds)), "none") or "none")
    write_metadata(fresh.path, summary, topics, compression, final=True, custom_data=_old_custom_data(bag_dir))


def recover_bag(path: str | os.PathLike) -> tuple[RecoveredFile, ...]:
    """Finalize every truncated .mcap of a bag dir (or a bare .mcap) and refresh metadata.yaml."""
    reader = BagReader(path)
    done = [_replace_file(f.path, f.path.with_name(f.path.name + ".truncated"))
            for f in reader.files if f.truncated]
    if done and reader.path.is_dir():
        _write_fresh_metadata(reader.path)
    return tuple(done)


def _channel_qos_incomplete(path: Path) -> bool:
    scan = FileScan()
    for _ in stream_records(path, scan):  # channels may be added at any point of a recording
        pass
    for ch in scan.channels.values():
        try:
            profiles = yaml.safe_load(ch.metadata.get("offered_qos_profiles", "") or "[]") or []
        except yaml.YAMLError:
            return True
        if not isinstance(profiles, list) or any(missing_keys(p) for p in profiles):
            return True
    return False


def _complete_channel_qos(bag_dir: Path) -> Callable[[Channel], dict]:
    reader = BagReader(bag_dir)
    qos = {t.name: complete_profiles(t.qos_profiles) for t in reader.topics.values()}

    def meta(channel: Channel) -> dict:
        out = dict(channel.metadata)
        profiles = qos.get(channel.topic, ())
        out["offered_qos_profiles"] = yaml.safe_dump([dict(p) for p in profiles], sort_keys=False) if profiles else ""
        return out
    return meta


def reindex_bag(path: str | os.PathLike, keep_backup: bool = True) -> ReindexResult:
    """Bring a bag directory's metadata.yaml and channel QoS up to complete rosbag2 v9 form."""
    bag_dir = Path(path)
    if not bag_dir.is_dir():
        raise BagError(f"{bag_dir} is not a bag directory (reindex writes its metadata.yaml)", "NOT_A_BAG_DIR")
    reader = BagReader(bag_dir)
    meta = _complete_channel_qos(bag_dir)
    done = []
    for f in reader.files:
        if f.truncated or _channel_qos_incomplete(f.path):
            backup = f.path.with_name(f.path.name + ".orig") if keep_backup else None
            done.append(_replace_file(f.path, backup, meta))
    before = (bag_dir / METADATA_FILE).read_text() if (bag_dir / METADATA_FILE).is_file() else None
    _write_fresh_metadata(bag_dir)
    after = (bag_dir / METADATA_FILE).read_text()
    return ReindexResult(bag_dir, tuple(done), before != after)

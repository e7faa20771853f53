"""Recover a killed recording so that every MCAP tool (rosbags, Foxglove, ros2 bag) opens it.

A SIGKILLed recorder leaves .mcap files without summary and footer. BagReader already reads
them up to the last complete chunk; `recover_bag` makes that permanent: each truncated file is
rewritten as a finalized MCAP holding exactly those messages (same schemas, channels, metadata
records and chunk compression), the original is kept beside it as `<name>.mcap.truncated`, and
metadata.yaml is regenerated from the files. Finalized files are never touched.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from mcap.writer import CompressionType, Writer

from skillgen_ros.core.bag.reader import BagReader, _records, _Scan
from skillgen_ros.core.bag.writer import (BagSummary, Compression, FileStats, TopicSpec,
                                          write_metadata)
from skillgen_ros.core.errors import BagError

_BY_NAME = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "": CompressionType.NONE}


@dataclass(frozen=True)
class RecoveredFile:
    path: Path
    backup: Path
    message_count: int


def _rewrite(src: Path, dst: Path) -> int:
    """Copy src's complete records into a new finalized MCAP at dst; returns messages written."""
    scan = _Scan()
    count = 0
    with open(dst, "xb") as out:
        writer: Writer | None = None
        schema_ids: dict[int, int] = {}
        channel_ids: dict[int, int] = {}
        for channel, msg in _records(src, scan):
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
                    dict(channel.metadata))
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


def recover_bag(path: str | os.PathLike) -> tuple[RecoveredFile, ...]:
    """Finalize every truncated .mcap of a bag dir (or a bare .mcap) and refresh metadata.yaml."""
    reader = BagReader(path)
    done = []
    for f in reader.files:
        if not f.truncated:
            continue
        backup = f.path.with_name(f.path.name + ".truncated")
        if backup.exists():
            raise BagError(f"{backup} already exists; move it away before recovering again", "BAG_EXISTS")
        tmp = f.path.with_name(f.path.name + ".recovering")
        tmp.unlink(missing_ok=True)
        n = _rewrite(f.path, tmp)
        os.replace(f.path, backup)
        os.replace(tmp, f.path)
        done.append(RecoveredFile(f.path, backup, n))
    if done and reader.path.is_dir():
        fresh = BagReader(reader.path)
        files = tuple(FileStats(x.path.name, x.start_ns, x.end_ns, x.message_count) for x in fresh.files)
        counted = [x for x in files if x.message_count]
        summary = BagSummary(
            path=fresh.path, files=files,
            topic_counts={t.name: t.message_count for t in fresh.topics.values()},
            message_count=fresh.message_count,
            start_ns=min((x.start_ns for x in counted), default=0),
            end_ns=max((x.end_ns for x in counted), default=0))
        topics = [TopicSpec(t.name, t.type, t.qos_profiles, t.serialization_format) for t in fresh.topics.values()]
        kinds = {c for x in fresh.files for c in x.compression}
        compression = Compression.parse(next(iter(sorted(kinds)), "none") or "none")
        write_metadata(fresh.path, summary, topics, compression, final=True)
    return tuple(done)

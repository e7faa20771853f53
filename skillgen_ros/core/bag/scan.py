"""One pass over an MCAP file: what it holds (schemas, channels, counts, times, compression).

A finalized file is read through its summary (indexed); a file without a footer (a recording
that was killed) is scanned record by record up to its last complete, CRC-valid chunk and marked
truncated instead of failing. BagReader (reader.py) and recover.py both read files this way.
Pure: no rclpy.
"""
from __future__ import annotations

import os
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, breakup_chunk

from skillgen_ros.core.bag.mcap_io import open_bounded as _open
from skillgen_ros.core.errors import BagError

MAGIC = b"\x89MCAP0\r\n"


@dataclass
class FileScan:
    """What one pass over a file found (filled in while `stream_records` runs; recover.py reads it)."""

    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    compression: set[str] = field(default_factory=set)
    chunks: int = 0
    start_ns: int = 0
    end_ns: int = 0
    truncated: bool = False
    library: str = ""


# What a cut-off or damaged tail raises inside mcap's stream reader.
TAIL_ERRORS = (McapError, struct.error, EOFError, ValueError, OSError, RuntimeError, MemoryError, KeyError)


def stream_records(path: Path, scan: FileScan) -> Iterator[tuple[Channel, Message]]:
    """Stream every message in file order, filling `scan` (schemas, channels, metadata records,
    chunk compressions) as records arrive; stop quietly (scan.truncated) at a damaged tail."""
    raw, f = _open(path)
    with raw:
        stream = StreamReader(f, skip_magic=True, emit_chunks=True, validate_crcs=True).records
        head = f.read(8)
        if head != MAGIC:
            if len(head) < len(MAGIC) and MAGIC.startswith(head):
                raise BagError(f"{path} is truncated inside its MCAP magic: nothing to recover",
                               "BAG_TRUNCATED")
            raise BagError(f"{path} is not an MCAP file (bad magic)", "NOT_MCAP")
        while True:
            try:
                record = next(stream)
                inner = breakup_chunk(record, validate_crc=True) if isinstance(record, Chunk) else [record]
            except StopIteration:
                return
            except TAIL_ERRORS:
                scan.truncated = True
                return
            if isinstance(record, Chunk):
                scan.chunks += 1
                scan.compression.add(record.compression)
            for rec in inner:
                if isinstance(rec, Schema):
                    scan.schemas[rec.id] = rec
                elif isinstance(rec, Channel):
                    scan.channels[rec.id] = rec
                elif isinstance(rec, Metadata):
                    scan.metadata[rec.name] = dict(rec.metadata)
                elif isinstance(rec, Message) and rec.channel_id in scan.channels:
                    yield scan.channels[rec.channel_id], rec
            if isinstance(record, Header):
                scan.library = record.library


def is_finalized(path: Path) -> bool:
    size = path.stat().st_size
    if size < 2 * len(MAGIC) + 29:
        return False
    with open(path, "rb") as f:
        f.seek(-len(MAGIC), os.SEEK_END)
        return f.read() == MAGIC


def scan_file(path: Path) -> FileScan:
    scan = FileScan()
    if is_finalized(path):
        try:
            raw, f = _open(path)
            with raw:
                reader = SeekingReader(f, validate_crcs=True)
                summary = reader.get_summary()
                if summary is not None and summary.statistics is not None:
                    stats = summary.statistics
                    scan.schemas, scan.channels = dict(summary.schemas), dict(summary.channels)
                    scan.counts = dict(stats.channel_message_counts)
                    scan.start_ns, scan.end_ns = stats.message_start_time, stats.message_end_time
                    scan.chunks = len(summary.chunk_indexes)
                    scan.compression = {c.compression for c in summary.chunk_indexes}
                    scan.metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
                    scan.library = reader.get_header().library
                    return scan
        except TAIL_ERRORS:
            scan = FileScan()  # damaged summary: fall back to the linear scan
    times = []
    for channel, msg in stream_records(path, scan):
        scan.counts[channel.id] = scan.counts.get(channel.id, 0) + 1
        times.append(msg.log_time)
    scan.truncated = scan.truncated or not is_finalized(path)
    if times:
        scan.start_ns, scan.end_ns = min(times), max(times)
    if not scan.channels and scan.truncated and path.stat().st_size <= len(MAGIC) + 9:
        raise BagError(f"{path} is truncated before its first record: nothing to recover",
                       "BAG_TRUNCATED")
    return scan

"""BagWriter: a rosbag2-layout bag directory (metadata.yaml + MCAP files) from serialized CDR.

Crash safety is the design driver. Each MCAP file is chunked and written unbuffered, so every
completed chunk is in the OS page cache the moment `write` returns: a SIGKILLed process leaves
a file whose complete chunks a streaming reader recovers (see reader.py). An open chunk is
closed once it is `max_chunk_age_s` old, bounding what a kill can lose for slow topics.
metadata.yaml is rewritten atomically at start, at each split, periodically and at close, so
a killed recording still has a (possibly stale) one; the reader rescans the MCAP files anyway.
Not thread-safe: one thread (the recorder's writer thread) owns a BagWriter.
"""
from __future__ import annotations

import enum
import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Mapping

import yaml
from mcap.writer import CompressionType, Writer

from skillgen_ros.core.bag import schemas
from skillgen_ros.core.bag.qos import complete_profiles
from skillgen_ros.core.errors import BagError

METADATA_FILE = "metadata.yaml"
_Dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
ROSBAG2_VERSION = 9
ANNOTATIONS_RECORD = "skillgen_annotations"


class Compression(str, enum.Enum):
    """MCAP chunk compression (rosbag2's storage-level compression for mcap)."""

    NONE = "none"
    ZSTD = "zstd"
    LZ4 = "lz4"

    @classmethod
    def parse(cls, value: str) -> "Compression":
        try:
            return cls((value or "none").lower())
        except ValueError:
            raise BagError(f"compression must be one of {[c.value for c in cls]}, got '{value}'",
                           "BAD_COMPRESSION") from None


_MCAP_COMPRESSION = {Compression.NONE: CompressionType.NONE, Compression.ZSTD: CompressionType.ZSTD,
                     Compression.LZ4: CompressionType.LZ4}


@dataclass(frozen=True)
class TopicSpec:
    """One recorded topic. qos_profiles: rosbag2 v9 QoS dicts of the publishers seen (the writer
    completes each one with the defaults of core/bag/qos.py, so partial dicts are fine)."""

    name: str
    type: str
    qos_profiles: tuple[Mapping, ...] = ()
    serialization_format: str = "cdr"


@dataclass(frozen=True)
class WriterOptions:
    compression: Compression = Compression.ZSTD
    chunk_size: int = 1 << 20          # bytes of uncompressed messages per chunk
    max_file_size: int = 0             # split to a new .mcap past this many bytes; 0 = never
    max_chunk_age_s: float = 1.0       # close a chunk this old even if not full (crash bound)
    metadata_interval_s: float = 2.0   # rewrite metadata.yaml at most this often while writing


@dataclass(frozen=True)
class FileStats:
    path: str                          # relative to the bag directory
    start_ns: int
    end_ns: int
    message_count: int


@dataclass(frozen=True)
class BagSummary:
    path: Path
    files: tuple[FileStats, ...]
    topic_counts: Mapping[str, int]
    message_count: int
    start_ns: int
    end_ns: int


class _UnbufferedSink:
    """File sink for mcap.Writer: every write goes straight to the OS; tracks the offset."""

    def __init__(self, path: Path):
        self._f = open(path, "xb", buffering=0)
        self.offset = 0

    def write(self, data) -> int:
        view = memoryview(data)
        while view:
            n = self._f.write(view)
            view = view[n:]
        self.offset += len(data)
        return len(data)

    def tell(self) -> int:
        return self.offset

    def flush(self) -> None:
        pass

    def close(self) -> None:
        self._f.close()


@dataclass
class _FileState:
    rel: str
    sink: _UnbufferedSink
    mcap: Writer
    channels: dict[str, int] = field(default_factory=dict)
    count: int = 0
    start_ns: int = 0
    end_ns: int = 0


def qos_yaml(profiles: tuple[Mapping, ...]) -> str:
    """The string rosbag2 stores in MCAP channel metadata `offered_qos_profiles`."""
    return yaml.safe_dump([dict(p) for p in profiles], sort_keys=False) if profiles else ""


class BagWriter:
    """Write serialized messages into a new rosbag2 bag directory (never into an existing bag)."""

    def __init__(self, path: str | os.PathLike, options: WriterOptions = WriterOptions(),
                 schema_lookup: Callable[[str], str] = schemas.schema_text,
                 clock: Callable[[], float] = time.monotonic):
        self.path = Path(path)
        if self.path.exists() and (not self.path.is_dir() or any(self.path.iterdir())):
            raise BagError(f"{self.path} already exists; refusing to overwrite a bag", "BAG_EXISTS")
        if options.chunk_size <= 0 or options.max_file_size < 0 or options.max_chunk_age_s <= 0:
            raise BagError(f"invalid writer options {options}", "BAD_OPTIONS")
        self.options = options
        self._schema_lookup = schema_lookup
        self._clock = clock
        self._topics: dict[str, TopicSpec] = {}
        self._schema_text: dict[str, str] = {}
        self._counts: dict[str, int] = {}
        self._closed_files: list[FileStats] = []
        self._file: _FileState | None = None
        self._chunk_opened_at: float | None = None
        self._last_meta = 0.0
        self._closed = False
        self.path.mkdir(parents=True, exist_ok=True)
        self._open_file()
        self._write_metadata(final=False)

    # -- public API -------------------------------------------------------------------------
    def add_topic(self, spec: TopicSpec) -> None:
        """Register a topic (its full schema is resolved now: BagError UNKNOWN_TYPE if not found)."""
        self._check_open()
        if spec.name in self._topics:
            if self._topics[spec.name].type != spec.type:
                raise BagError(f"topic {spec.name} already recorded as {self._topics[spec.name].type}, "
                               f"not {spec.type}", "TYPE_CONFLICT")
            return
        schemas.split_type(spec.type)
        spec = replace(spec, qos_profiles=complete_profiles(spec.qos_profiles))
        if spec.type not in self._schema_text:
            self._schema_text[spec.type] = self._schema_lookup(spec.type)
        self._topics[spec.name] = spec
        self._counts[spec.name] = 0
        self._register(self._file, spec)

    @property
    def topics(self) -> Mapping[str, TopicSpec]:
        return dict(self._topics)

    def write(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Append one serialized message; may close a chunk and split to a new file."""
        self._check_open()
        f = self._file
        cid = f.channels.get(topic)
        if cid is None:
            raise BagError(f"topic {topic} was not added to the bag", "UNKNOWN_TOPIC")
        before = f.sink.offset
        seq = self._counts[topic]
        f.mcap.add_message(cid, log_time=log_time_ns,
                           publish_time=log_time_ns if publish_time_ns is None else publish_time_ns,
                           data=data, sequence=seq & 0xFFFFFFFF)
        self._counts[topic] = seq + 1
        f.start_ns = log_time_ns if f.count == 0 else min(f.start_ns, log_time_ns)
        f.end_ns = max(f.end_ns, log_time_ns)
        f.count += 1
        if f.sink.offset != before:
            self._chunk_opened_at = None
        elif self._chunk_opened_at is None:
            self._chunk_opened_at = self._clock()
        self.tick()

    def tick(self) -> None:
        """Close an aged chunk, split if the file is full, refresh metadata.yaml. Call when idle."""
        if self._closed:
            return
        now = self._clock()
        if self._chunk_opened_at is not None and now - self._chunk_opened_at >= self.options.max_chunk_age_s:
            self._file.mcap.flush()
            self._chunk_opened_at = None
        if self.options.max_file_size and self._file.sink.offset >= self.options.max_file_size \
                and self._file.count > 0:
            self._file.mcap.flush()
            self._chunk_opened_at = None
            if self._file.sink.offset >= self.options.max_file_size:
                self._split()
        if now - self._last_meta >= self.options.metadata_interval_s:
            self._write_metadata(final=False)

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Store an MCAP metadata record (e.g. ANNOTATIONS_RECORD) in the current file."""
        self._check_open()
        record = {str(k): str(v) for k, v in data.items()}
        self._file.mcap.add_metadata(name, record)

    def close(self) -> BagSummary:
        """Finish the current MCAP file (summary + footer) and write the final metadata.yaml."""
        if not self._closed:
            self._finish_file()
            self._closed = True
            self._write_metadata(final=True)
        return self.summary()

    def summary(self) -> BagSummary:
        files = tuple(self._closed_files) + ((self._stats(self._file),) if self._file else ())
        counted = [f for f in files if f.message_count]
        return BagSummary(
            path=self.path, files=files, topic_counts=dict(self._counts),
            message_count=sum(f.message_count for f in files),
            start_ns=min((f.start_ns for f in counted), default=0),
            end_ns=max((f.end_ns for f in counted), default=0))

    def __enter__(self) -> "BagWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- internals --------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self._closed:
            raise BagError(f"bag {self.path} is already closed", "BAG_CLOSED")

    def _open_file(self) -> None:
        index = len(self._closed_files)
        rel = f"{self.path.name}_{index}.mcap"
        sink = _UnbufferedSink(self.path / rel)
        mcap = Writer(sink, chunk_size=self.options.chunk_size,
                      compression=_MCAP_COMPRESSION[self.options.compression])
        mcap.start(profile="ros2", library="skillgen_ros")
        self._file = _FileState(rel=rel, sink=sink, mcap=mcap)
        for spec in self._topics.values():
            self._register(self._file, spec)

    def _register(self, f: _FileState, spec: TopicSpec) -> None:
        sid = f.mcap.register_schema(spec.type, "ros2msg", self._schema_text[spec.type].encode())
        meta = {"offered_qos_profiles": qos_yaml(spec.qos_profiles)}
        digest = schemas.type_hash(spec.type)
        if digest:
            meta["topic_type_hash"] = digest
        f.channels[spec.name] = f.mcap.register_channel(spec.name, spec.serialization_format, sid, meta)

    def _finish_file(self) -> None:
        f = self._file
        f.mcap.finish()
        f.sink.close()
        self._closed_files.append(self._stats(f))
        self._file = None
        self._chunk_opened_at = None

    def _split(self) -> None:
        self._finish_file()
        self._open_file()
        self._write_metadata(final=False)

    @staticmethod
    def _stats(f: _FileState) -> FileStats:
        return FileStats(path=f.rel, start_ns=f.start_ns, end_ns=f.end_ns, message_count=f.count)

    def _write_metadata(self, final: bool) -> None:
        write_metadata(self.path, self.summary(), list(self._topics.values()), self.options.compression, final)
        self._last_meta = self._clock()


def write_metadata(bag_dir: Path, s: BagSummary, topics: list[TopicSpec], compression: Compression,
                   final: bool, custom_data: Mapping[str, str] | None = None) -> None:
    """Atomically (re)write a bag's rosbag2 metadata.yaml (version 9) from a summary.

    custom_data: extra entries kept (bag reindex passes the old file's); ours win on a clash."""
    info = {
        "version": ROSBAG2_VERSION,
        "storage_identifier": "mcap",
        "relative_file_paths": [f.path for f in s.files],
        "duration": {"nanoseconds": max(0, s.end_ns - s.start_ns)},
        "starting_time": {"nanoseconds_since_epoch": s.start_ns},
        "message_count": s.message_count,
        "topics_with_message_count": [
            {"topic_metadata": {
                "name": t.name, "type": t.type, "serialization_format": t.serialization_format,
                "offered_qos_profiles": list(complete_profiles(t.qos_profiles)),
                "type_description_hash": schemas.type_hash(t.type)},
             "message_count": s.topic_counts.get(t.name, 0)}
            for t in topics],
        # MCAP chunk compression is storage-internal, as in rosbag2's mcap plugin.
        "compression_format": "",
        "compression_mode": "",
        "files": [{"path": f.path, "starting_time": {"nanoseconds_since_epoch": f.start_ns},
                   "duration": {"nanoseconds": max(0, f.end_ns - f.start_ns)},
                   "message_count": f.message_count} for f in s.files],
        "custom_data": {**dict(custom_data or {}), "skillgen.chunk_compression": compression.value,
                        "skillgen.finalized": "true" if final else "false"},
        "ros_distro": "jazzy",
    }
    tmp = bag_dir / (METADATA_FILE + ".tmp")
    tmp.write_text(yaml.dump({"rosbag2_bagfile_information": info}, Dumper=_Dumper, sort_keys=False))
    os.replace(tmp, bag_dir / METADATA_FILE)

"""BagReader: messages and topic metadata from a rosbag2 bag directory or a bare .mcap file.

Finalized MCAP files are read through their summary (indexed, time-ordered). A file without a
footer (a recording that was killed) is scanned record by record and read up to its last
complete, CRC-valid chunk; the reader notes it in `warnings` instead of failing. The MCAP
files themselves are the truth: a missing or stale metadata.yaml only contributes QoS
profiles and type hashes. Every failure is a BagError with a reason code. Pure: no rclpy.
"""
from __future__ import annotations

import heapq
import importlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Iterator, Mapping

import yaml
from mcap.reader import SeekingReader
from mcap.records import Channel, Message, Schema

from skillgen_ros.core.bag.mcap_io import open_bounded as _open, reader_pos
from skillgen_ros.core.bag.scan import TAIL_ERRORS, FileScan, scan_file, stream_records
from skillgen_ros.core.bag.schemas import split_type
from skillgen_ros.core.bag.writer import METADATA_FILE
from skillgen_ros.core.errors import BagError

@dataclass(frozen=True)
class BagTopic:
    name: str
    type: str
    message_count: int
    serialization_format: str
    qos_profiles: tuple[Mapping, ...]
    type_hash: str
    schema_text: str


@dataclass(frozen=True)
class BagMessage:
    topic: str
    type: str
    data: bytes
    log_time_ns: int
    publish_time_ns: int


@dataclass(frozen=True)
class McapFileInfo:
    path: Path
    size_bytes: int
    message_count: int
    start_ns: int
    end_ns: int
    compression: tuple[str, ...]       # chunk compressions seen ('' = uncompressed)
    chunk_count: int
    truncated: bool                    # no footer: read up to the last complete chunk
    library: str


def _load_metadata_yaml(bag_dir: Path, warnings: list[str]) -> dict | None:
    meta = bag_dir / METADATA_FILE
    if not meta.is_file():
        warnings.append(f"{meta} is missing; reading the .mcap files directly")
        return None
    try:
        doc = yaml.safe_load(meta.read_text())
        return doc["rosbag2_bagfile_information"]
    except (yaml.YAMLError, KeyError, TypeError) as e:
        warnings.append(f"{meta} is unreadable ({type(e).__name__}); reading the .mcap files directly")
        return None


class BagReader:
    """Open a bag (directory or bare .mcap). Reading never modifies any file."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self.warnings: list[str] = []
        self.bag_metadata: dict | None = None
        if not self.path.exists():
            raise BagError(f"bag path {self.path} does not exist", "BAG_NOT_FOUND")
        if self.path.is_dir():
            paths = self._dir_files()
        elif self.path.suffix == ".mcap" or self.path.is_file():
            paths = [self.path]
        else:
            raise BagError(f"{self.path} is neither a bag directory nor an .mcap file", "NOT_A_BAG")
        self._scans: dict[Path, FileScan] = {}
        for p in paths:
            try:
                self._scans[p] = scan_file(p)
            except PermissionError as e:
                raise BagError(f"cannot read {p}: {e.strerror}", "BAG_UNREADABLE") from None
            if self._scans[p].truncated:
                self.warnings.append(
                    f"BAG_TRUNCATED: {p.name} has no valid footer; read "
                    f"{sum(self._scans[p].counts.values())} messages up to its last complete chunk")
        self.files = tuple(self._file_info(p, s) for p, s in self._scans.items())
        self.topics = self._collect_topics()
        self.metadata_records = {k: v for s in self._scans.values() for k, v in s.metadata.items()}
        self._decoders: dict = {}

    # -- summary ----------------------------------------------------------------------------
    @property
    def message_count(self) -> int:
        return sum(f.message_count for f in self.files)

    @property
    def start_ns(self) -> int:
        return min((f.start_ns for f in self.files if f.message_count), default=0)

    @property
    def end_ns(self) -> int:
        return max((f.end_ns for f in self.files if f.message_count), default=0)

    @property
    def truncated(self) -> bool:
        return any(f.truncated for f in self.files)

    # -- messages ---------------------------------------------------------------------------
    def messages(self, topics: Iterable[str] | None = None, start_ns: int | None = None,
                 end_ns: int | None = None) -> Iterator[BagMessage]:
        """All messages in log-time order (merged across split files); [start_ns, end_ns)."""
        wanted = None if topics is None else set(topics)
        unknown = (wanted or set()) - set(self.topics)
        if unknown:
            raise BagError(f"topics {sorted(unknown)} are not in {self.path}; it has "
                           f"{sorted(self.topics)}", "UNKNOWN_TOPIC")
        streams = [self._file_messages(p, s, wanted, start_ns, end_ns) for p, s in self._scans.items()]
        yield from heapq.merge(*streams, key=lambda m: m.log_time_ns)

    def _file_messages(self, path: Path, scan: FileScan, wanted, start_ns, end_ns) -> Iterator[BagMessage]:
        def keep(channel: Channel, msg: Message) -> bool:
            return ((wanted is None or channel.topic in wanted)
                    and (start_ns is None or msg.log_time >= start_ns)
                    and (end_ns is None or msg.log_time < end_ns))

        def make(schema_name: str, channel: Channel, msg: Message) -> BagMessage:
            return BagMessage(channel.topic, schema_name, bytes(msg.data), msg.log_time, msg.publish_time)

        if not scan.truncated:
            raw, f = _open(path)
            with raw:
                reader = SeekingReader(f, validate_crcs=True)  # a flipped bit is an error, never silent
                it = reader.iter_messages(topics=None if wanted is None else list(wanted), log_time_order=True,
                                          starting_at=start_ns, ending_before=end_ns)
                while True:
                    try:
                        schema, channel, msg = next(it)
                    except StopIteration:
                        return
                    except TAIL_ERRORS as e:  # CRC mismatch, undecompressable chunk, absurd length
                        raise BagError(f"{path}: damaged chunk after {reader_pos(f)} bytes "
                                       f"({type(e).__name__}: {e}); `skillgen bag recover` cannot repair a "
                                       f"finalized file, re-record it", "BAG_CORRUPT") from None
                    yield make(schema.name if schema else "", channel, msg)
        # Killed recording: file order is receive order; sort within the file's recovered part.
        rescan = FileScan()
        batch = [make(rescan.schemas[c.schema_id].name if c.schema_id in rescan.schemas else "", c, m)
                 for c, m in stream_records(path, rescan) if keep(c, m)]
        batch.sort(key=lambda m: m.log_time_ns)
        yield from batch

    def decode(self, message: BagMessage):
        """Deserialize with the bag's own schema through mcap_ros2's public DecoderFactory, no ROS
        install needed: field names as in the .msg, nested messages as objects, arrays as lists.
        BagError BAD_SCHEMA if the schema does not parse, BAD_MESSAGE if the bytes do not decode."""
        decoder = self._decoders.get(message.type)
        if decoder is None:
            topic = next((t for t in self.topics.values() if t.type == message.type), None)
            decoder = schema_decoder(message.type, topic.schema_text if topic else "")
            self._decoders[message.type] = decoder
        try:
            return decoder(message.data)
        except Exception as e:  # the CDR reader raises plain errors on garbage bytes
            raise BagError(f"cannot decode a {message.type} message on {message.topic}: "
                           f"{type(e).__name__}: {e}", "BAD_MESSAGE") from None

    # -- internals --------------------------------------------------------------------------
    def _dir_files(self) -> list[Path]:
        self.bag_metadata = _load_metadata_yaml(self.path, self.warnings)
        found = sorted(self.path.glob("*.mcap"), key=lambda p: (len(p.name), p.name))
        listed: list[Path] = []
        if self.bag_metadata is not None:
            if self.bag_metadata.get("storage_identifier", "mcap") != "mcap":
                raise BagError(f"{self.path} uses storage '{self.bag_metadata.get('storage_identifier')}';"
                               " only mcap is supported", "UNSUPPORTED_STORAGE")
            for rel in self.bag_metadata.get("relative_file_paths") or []:
                p = self.path / Path(str(rel)).name
                if p.exists():
                    listed.append(p)
                else:
                    self.warnings.append(f"metadata.yaml lists {rel}, which is missing")
        paths = listed + [p for p in found if p not in listed]
        if not paths:
            raise BagError(f"{self.path} holds no .mcap files", "BAG_EMPTY")
        return paths

    @staticmethod
    def _file_info(path: Path, s: FileScan) -> McapFileInfo:
        return McapFileInfo(path=path, size_bytes=path.stat().st_size,
                            message_count=sum(s.counts.values()), start_ns=s.start_ns, end_ns=s.end_ns,
                            compression=tuple(sorted(s.compression)), chunk_count=s.chunks,
                            truncated=s.truncated, library=s.library)

    def _collect_topics(self) -> dict[str, BagTopic]:
        yaml_topics = {}
        for entry in (self.bag_metadata or {}).get("topics_with_message_count") or []:
            tm = entry.get("topic_metadata", {}) if isinstance(entry, dict) else {}
            if "name" in tm:
                yaml_topics[tm["name"]] = tm
        counts: dict[str, int] = {}
        first: dict[str, tuple[Channel, Schema | None]] = {}
        for s in self._scans.values():
            for cid, ch in s.channels.items():
                counts[ch.topic] = counts.get(ch.topic, 0) + s.counts.get(cid, 0)
                first.setdefault(ch.topic, (ch, s.schemas.get(ch.schema_id)))
        topics = {}
        for name, (ch, schema) in first.items():
            tm = yaml_topics.get(name, {})
            qos = tm.get("offered_qos_profiles")
            if not qos:
                try:
                    qos = yaml.safe_load(ch.metadata.get("offered_qos_profiles", "") or "[]")
                except yaml.YAMLError:
                    qos = []
            topics[name] = BagTopic(
                name=name, type=schema.name if schema else tm.get("type", ""),
                message_count=counts[name], serialization_format=ch.message_encoding,
                qos_profiles=tuple(q for q in (qos or []) if isinstance(q, dict)),
                type_hash=ch.metadata.get("topic_type_hash", "") or tm.get("type_description_hash", ""),
                schema_text=schema.data.decode(errors="replace") if schema else "")
        return topics


def schema_decoder(type_name: str, schema_text: str):
    """bytes -> decoded message for one ros2msg schema (mcap_ros2.decoder.DecoderFactory).

    BagError BAD_SCHEMA when the schema text is empty or does not parse."""
    from mcap_ros2.decoder import DecoderFactory

    try:
        decoder = DecoderFactory().decoder_for("cdr", Schema(id=1, name=type_name, encoding="ros2msg",
                                                             data=schema_text.encode()))
    except Exception as e:  # the schema parser raises several error types
        raise BagError(f"cannot parse the bag's schema for {type_name}: {type(e).__name__}: {e}",
                       "BAD_SCHEMA") from None
    if decoder is None or not schema_text.strip():
        raise BagError(f"the bag has no ros2msg schema for {type_name}", "BAD_SCHEMA")
    return decoder


def message_class(type_name: str):
    """The installed Python class for a type (msg, srv/action parts); BagError TYPE_NOT_INSTALLED."""
    pkg, kind, name = split_type(type_name)
    try:
        module = importlib.import_module(f"{pkg}.{kind}")
        if kind == "msg":
            return getattr(module, name)
        base, _, part = name.partition("_")
        cls = getattr(module, base)
        for attr in part.split("_") if part else []:
            cls = getattr(cls, attr, None) or getattr(cls.Impl, attr + ("Service" if attr in (
                "SendGoal", "GetResult") else ""))
        return cls
    except (ImportError, AttributeError):
        raise BagError(f"message type '{type_name}' is not installed (no Python module for it); "
                       f"install its interface package to replay or decode it",
                       "TYPE_NOT_INSTALLED") from None


def playable_topics(reader: BagReader) -> tuple[list[str], list[str]]:
    """(topics whose types this machine can publish, the others as 'name (type)'): replaying a
    whole bag skips the second list (a session bag's /tf is tf2_msgs, which is not on PyPI)."""
    ok, skipped = [], []
    for name in sorted(reader.topics):
        t = reader.topics[name].type
        try:
            message_class(t)
            ok.append(name)
        except BagError:
            skipped.append(f"{name} ({t})")
    return ok, skipped


def check_installed(reader: BagReader, topics: Iterable[str] | None = None) -> None:
    """Raise TYPE_NOT_INSTALLED naming every topic whose type this machine lacks."""
    names = list(topics) if topics is not None else list(reader.topics)
    unknown = [n for n in names if n not in reader.topics]
    if unknown:
        raise BagError(f"topics {unknown} are not in {reader.path}; it has {sorted(reader.topics)}",
                       "UNKNOWN_TOPIC")
    missing = []
    for name in names:
        t = reader.topics[name].type
        try:
            message_class(t)
        except BagError:
            missing.append(f"{name} ({t})")
    if missing:
        raise BagError(f"message types not installed for topics: {', '.join(missing)}",
                       "TYPE_NOT_INSTALLED")

"""recorder node: record topics as serialized CDR into a rosbag2-layout MCAP bag (core/bag).

Subscribes raw (no deserialization) to `topics`, or with `all_topics` to every topic the graph
poll discovers, each with a QoS that matches all of its publishers. The subscriptions live on a
hidden helper node (`_<name>_io`) spun by its own single-threaded executor thread: rclpy's
MultiThreadedExecutor (run_node's) takes messages too slowly on a loaded machine and lost half
of a 500 Hz stream in the benchmark. Callbacks only stamp and enqueue; a dedicated writer
thread owns the BagWriter, so neither executor ever blocks on disk or compression.
With `scene`, the recorder also writes what Foxglove's 3D panel needs, synthesized from the
graph's topics by core/viz (nodes/scene_feed.py): /tf and /tf_static (tf2_msgs/msg/TFMessage; no
node publishes /tf because rclpy cannot import tf2_msgs on a pip install), /robot_description and
/scene/object_markers (docs/foxglove.md). `throttle` records some topics at a low rate (the
front point cloud). Services `recorder/{start,stop,pause,resume}` (skillgen_interfaces/srv/Recorder). SIGINT and
SIGTERM reach `destroy_node` through run_node's shutdown path, which finalizes the bag; after a
SIGKILL every completed chunk stays readable (see core/bag/writer.py).
"""
from __future__ import annotations

import enum
import queue
import sys
import threading
import time
from datetime import datetime, timezone
from pathlib import Path

from rcl_interfaces.msg import ParameterDescriptor
import rclpy
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from skillgen_interfaces.srv import Recorder as RecorderSrv
from skillgen_ros.core.bag.reader import message_class
from skillgen_ros.core.bag.writer import BagWriter, Compression, TopicSpec, WriterOptions
from skillgen_ros.core import validation as V
from skillgen_ros.core.errors import BagError, ParameterError, SkillGenError
from skillgen_ros.nodes.bag_qos import qos_to_dict, subscription_qos
from skillgen_ros.nodes.runtime import run_node
from skillgen_ros.core.viz.scene import SCENE_TOPICS, VizMessage


class State(enum.Enum):
    IDLE = "idle"
    RECORDING = "recording"
    PAUSED = "paused"


_CLOSE = object()


class _WriterThread(threading.Thread):
    """Owns one BagWriter; drains (topic, data, log_ns, pub_ns) items and TopicSpecs."""

    def __init__(self, writer: BagWriter, logger, max_queue_bytes: int):
        super().__init__(name="bag-writer", daemon=True)
        self.writer = writer
        self.queue: queue.SimpleQueue = queue.SimpleQueue()
        self.max_queue_bytes = max_queue_bytes
        self.queued_bytes = 0
        self.dropped = 0
        self.error: SkillGenError | None = None
        self._logger = logger
        self._lock = threading.Lock()

    def put_message(self, topic: str, data: bytes, log_ns: int, pub_ns: int) -> None:
        with self._lock:
            if self.queued_bytes + len(data) > self.max_queue_bytes:
                self.dropped += 1
                return
            self.queued_bytes += len(data)
        self.queue.put((topic, data, log_ns, pub_ns))

    def run(self) -> None:
        while True:
            try:
                item = self.queue.get(timeout=0.2)
            except queue.Empty:
                self.writer.tick()
                continue
            if item is _CLOSE:
                return
            try:
                if isinstance(item, TopicSpec):
                    self.writer.add_topic(item)
                    continue
                topic, data, log_ns, pub_ns = item
                with self._lock:
                    self.queued_bytes -= len(data)
                self.writer.write(topic, data, log_ns, pub_ns)
            except (SkillGenError, OSError) as e:  # e.g. disk full: say so, keep draining
                self.error = e
                self._logger.error(str(e))

    def close(self):
        """Drain everything queued, then finalize the bag; returns the BagSummary."""
        self.queue.put(_CLOSE)
        self.join()
        return self.writer.close()


# name -> (default, description): the recorder's parameters (params/recorder.yaml sets them)
PARAMETERS = {
    "output": ("", "bag directory; empty: bags/rec_<UTC time>"),
    "topics": ([""], "topics to record (relative names resolve in the node namespace)"),
    "all_topics": (False, "record every discovered topic"),
    "exclude": (["/rosout", "/parameter_events"], "never record"),
    "include_hidden": (False, "also record hidden (/_x) topics"),
    "max_bag_size": (0, "split to a new .mcap past this many bytes; 0 never"),
    "compression": ("lz4", "MCAP chunk compression: lz4 (fast), zstd (smaller, ~4x the CPU), none"),
    "chunk_size": (1 << 20, "uncompressed bytes per MCAP chunk"),
    "max_chunk_age": (1.0, "s; close a chunk this old (kill-safety bound)"),
    "autostart": (True, "start recording at launch"),
    "discovery_period": (0.5, "s between graph polls"),
    "queue_depth": (1000, "subscription history depth (absorbs stalls)"),
    "max_queue_bytes": (1 << 30, "writer backlog cap; beyond it messages drop"),
    "scene": (False, "also write /tf, /tf_static, /robot_description and /scene/object_markers for Foxglove "
                     "(docs/foxglove.md)"),
    "scene_cameras": (["front", "wrist"], "cameras whose pose frames /tf gets"),
    "throttle": ([""], "'topic=seconds' entries: record at most one message per that many seconds on the topic"),
    "writable_roots": ([""], "extra directories a recorder/start output may lie under (the working and temp "
                             "dirs always)"),
}


class Recorder(Node):
    """Raw-CDR recorder with start/stop/pause/resume services."""

    def __init__(self):
        super().__init__("recorder")
        for name, (default, desc) in PARAMETERS.items():
            self.declare_parameter(name, default, ParameterDescriptor(description=desc))
        p = {n: self.get_parameter(n).value for n in PARAMETERS}
        self._read_parameters(p)
        self._lock = threading.Lock()
        self._state = State.IDLE
        self._writer: _WriterThread | None = None
        self._bag_path: Path | None = None
        self._subs: dict[str, object] = {}
        self._specs: dict[str, TopicSpec] = {}
        self._skipped: set[str] = set()
        self.received = 0
        self.skipped = 0
        self._io_node = rclpy.create_node(f"_{self.get_name()}_io", namespace=self.get_namespace(),
                                          context=self.context)
        self._io_exec = SingleThreadedExecutor(context=self.context)
        self._io_exec.add_node(self._io_node)
        self._io_thread = threading.Thread(target=self._spin_io, name="recorder-io", daemon=True)
        self._io_thread.start()
        try:  # from here a failure (or Ctrl-C) must stop the io thread: see _close
            srv_group = MutuallyExclusiveCallbackGroup()
            for name, handler in (("start", self._on_start), ("stop", self._on_stop),
                                  ("pause", self._on_pause), ("resume", self._on_resume)):
                self.create_service(RecorderSrv, f"recorder/{name}", handler, callback_group=srv_group)
            self.create_timer(float(p["discovery_period"]), self._discover, callback_group=srv_group)
            if p["autostart"]:
                ok, msg = self.start()
                if not ok:
                    raise BagError(msg, "RECORDER_START_FAILED")
        except BaseException:
            self._close()
            raise

    def _read_parameters(self, p: dict) -> None:
        """The parameters, checked (ParameterError names the bad one), as the node's settings."""
        try:
            compression = Compression.parse(p["compression"])
        except BagError as e:
            raise ParameterError(str(e)) from None
        if p["max_bag_size"] < 0 or p["chunk_size"] <= 0 or p["queue_depth"] <= 0:
            raise ParameterError("max_bag_size >= 0, chunk_size > 0 and queue_depth > 0 are required")
        try:  # NaN and inf fail these
            V.finite("discovery_period", p["discovery_period"], 0.0, 3600.0, lo_open=True)
            V.finite("max_chunk_age", p["max_chunk_age"], 0.0, 3600.0, lo_open=True)
        except SkillGenError as e:
            raise ParameterError(str(e.args[0])) from None
        self._roots = [r for r in p["writable_roots"] if r]
        if p["output"]:
            self._roots.append(str(Path(p["output"]).resolve().parent))
        self._options = WriterOptions(compression=compression, chunk_size=int(p["chunk_size"]),
                                      max_file_size=int(p["max_bag_size"]),
                                      max_chunk_age_s=float(p["max_chunk_age"]))
        self._output = p["output"]
        self._topics = [self.resolve_topic_name(t) for t in p["topics"] if t]
        self._all = bool(p["all_topics"])
        self._exclude = set(p["exclude"])
        self._hidden = bool(p["include_hidden"])
        self._depth = int(p["queue_depth"])
        self._max_queue = int(p["max_queue_bytes"])
        self._scene = bool(p["scene"])
        self._scene_cameras = [c for c in p["scene_cameras"] if c]
        self._feed = None
        try:
            self._throttle = {self.resolve_topic_name(t): ns for t, ns in
                              _parse_throttle([t for t in p["throttle"] if t]).items()}
        except SkillGenError:
            raise
        except Exception as e:  # noqa: BLE001 -- rclpy's InvalidTopicNameException
            raise ParameterError(f"throttle: invalid topic name: {e}") from None
        self._last_ns: dict[str, int] = {}
        if self._scene:
            self._exclude |= set(SCENE_TOPICS)  # written by the synthesizer, never twice

    # -- control ----------------------------------------------------------------------------
    def _checked(self, output: str, topics: list[str]) -> list[str]:
        """A start request's output (under the writable roots) and topics (valid names), resolved."""
        if output:
            V.writable_path("output", output, self._roots)
        V.names("topics", topics, allow_empty=True, reason="INVALID_TOPIC")
        try:
            return [self.resolve_topic_name(t) for t in topics if t]
        except Exception as e:  # noqa: BLE001 -- rclpy's InvalidTopicNameException and friends
            raise BagError(f"invalid topic name in {topics[:8]}: {e}", "INVALID_TOPIC") from None

    def start(self, output: str = "", topics: list[str] | None = None) -> tuple[bool, str]:
        try:
            resolved = self._checked(output, list(topics or []))
        except SkillGenError as e:
            return False, str(e)
        with self._lock:
            if self._state != State.IDLE:
                return False, f"BUSY: already {self._state.value} to {self._bag_path}"
            if resolved:
                self._topics = resolved
            if not self._topics and not self._all:
                return False, "NO_TOPICS: no topics to record: set 'topics' or 'all_topics'"
            stamp = datetime.now(timezone.utc).strftime("rec_%Y%m%d_%H%M%S_%f")
            path = Path(output or self._output or str(Path("bags") / stamp))
            try:
                writer = BagWriter(path, self._options)
            except (SkillGenError, OSError) as e:
                return False, str(e)
            self._writer = _WriterThread(writer, self.get_logger(), self._max_queue)
            self._writer.start()
            self._bag_path = path.resolve()
            for spec in self._specs.values():  # re-declare topics subscribed before a stop
                self._writer.queue.put(spec)
            if self._scene:
                for topic, (type_name, latched) in SCENE_TOPICS.items():
                    self._writer.queue.put(TopicSpec(topic, type_name, ({
                        "history": "keep_last", "depth": 1, "reliability": "reliable",
                        "durability": "transient_local" if latched else "volatile"},)))
            self._state = State.RECORDING  # after the specs: a message is only queued after its topic's spec
            if self._scene:  # after RECORDING: a latched input delivered as the subscription is made counts
                self._start_scene()
        self.get_logger().info(f"recording to {self._bag_path}")
        self._discover()
        return True, f"recording to {self._bag_path}"

    def stop(self) -> tuple[bool, str]:
        with self._lock:
            if self._state == State.IDLE or self._writer is None:
                return False, "NOT_RECORDING: not recording"
            writer, self._writer = self._writer, None
            self._state = State.IDLE
        summary = writer.close()
        msg = (f"bag {summary.path} finalized: {summary.message_count} messages in {len(summary.files)} "
               f"file(s); {writer.dropped} dropped")
        if self.context.ok():
            self.get_logger().info(msg)
        else:  # shutting down (SIGINT/SIGTERM): rosout is gone, say it on stderr
            print(f"[recorder] {msg}", file=sys.stderr, flush=True)
        return True, msg

    def _set_paused(self, paused: bool) -> tuple[bool, str]:
        with self._lock:
            want_from = State.RECORDING if paused else State.PAUSED
            if self._state != want_from:
                return False, (f"BAD_STATE: cannot {'pause' if paused else 'resume'} while {self._state.value} "
                               f"({self.received} recorded, {self.skipped} skipped)")
            self._state = State.PAUSED if paused else State.RECORDING
        return True, f"{self._state.value} ({self.received} recorded, {self.skipped} skipped)"

    def _respond(self, response, result: tuple[bool, str]):
        response.success, response.message = result
        response.bag_path = str(self._bag_path or "")
        return response

    def _on_start(self, req, res):
        return self._respond(res, self.start(req.output, list(req.topics)))

    def _on_stop(self, req, res):
        return self._respond(res, self.stop())

    def _on_pause(self, req, res):
        return self._respond(res, self._set_paused(True))

    def _on_resume(self, req, res):
        return self._respond(res, self._set_paused(False))

    # -- discovery and subscriptions -------------------------------------------------------
    def _wanted(self, topic: str) -> bool:
        if topic in self._exclude:
            return False
        if self._topics and topic in self._topics:
            return True
        hidden = any(part.startswith("_") for part in topic.split("/"))
        return self._all and (self._hidden or not hidden)

    def _discover(self) -> None:
        if self._state == State.IDLE:
            return
        for topic, types in self.get_topic_names_and_types():
            if topic in self._subs or not types or not self._wanted(topic):
                continue
            infos = self.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            type_name = types[0]
            try:
                cls = message_class(type_name)
            except BagError as e:
                if topic not in self._skipped:
                    self._skipped.add(topic)
                    self.get_logger().warn(f"not recording {topic}: {e}")
                continue
            spec = TopicSpec(topic, type_name, tuple(qos_to_dict(i.qos_profile) for i in infos))
            qos = subscription_qos([i.qos_profile for i in infos], self._depth)
            sub = self._io_node.create_subscription(
                cls, topic, lambda data, info, t=topic: self._on_message(t, data, info), qos, raw=True)
            with self._lock:
                self._subs[topic] = sub
                self._specs[topic] = spec
                if self._writer is not None:
                    self._writer.queue.put(spec)
            self.get_logger().info(f"recording {topic} [{type_name}] "
                                   f"({qos.reliability.name.lower()}, {qos.durability.name.lower()})")

    def _start_scene(self) -> None:
        """Scene subscriptions are made at the first start (a graph that never records pays nothing)."""
        if self._feed is None:
            from skillgen_ros.nodes.scene_feed import SceneFeed

            self._feed = SceneFeed(self._io_node, self._on_scene, self._scene_cameras,
                                   active=lambda: self._state == State.RECORDING)
        self._feed.synth.reset()  # the new bag gets the latched scene topics again

    def _on_scene(self, msg: VizMessage, log_ns: int) -> None:
        writer = self._writer
        if writer is not None and self._state == State.RECORDING:
            writer.put_message(msg.topic, msg.data, log_ns, log_ns)

    def _on_message(self, topic: str, data: bytes, info) -> None:
        writer = self._writer
        if writer is None or self._state != State.RECORDING:
            self.skipped += 1  # arrived while paused or stopped (reported by the services)
            return
        log_ns = info.get("received_timestamp") or time.time_ns()
        period = self._throttle.get(topic)
        if period is not None:
            if log_ns - self._last_ns.get(topic, -period) < period:
                return
            self._last_ns[topic] = log_ns
        self.received += 1
        writer.put_message(topic, data, log_ns, info.get("source_timestamp") or log_ns)

    def _spin_io(self) -> None:
        try:
            self._io_exec.spin()
        except (ExternalShutdownException, KeyboardInterrupt):
            pass
        except Exception:  # noqa: BLE001 - a shutdown between two waits is RCLError "failed to initialize
            if self.context.ok():  # wait set: the given context is not valid" (suite run at load ~6): a stop
                raise

    def _close(self) -> None:
        """Finalize the bag and stop the io thread. A process that exits with an executor still
        spinning aborts ("terminate called without an active exception"): seen when Ctrl-C landed
        while the node was being built, so that path closes too."""
        if self._state != State.IDLE:
            self.stop()
        self._io_exec.shutdown(timeout_sec=1.0)
        self._io_thread.join(timeout=2.0)
        self._io_node.destroy_node()

    def destroy_node(self):
        """Shutdown path (SIGINT/SIGTERM via run_node): finalize the bag before going away."""
        self._close()
        return super().destroy_node()


def _parse_throttle(entries: list[str]) -> dict[str, int]:
    """'topic=seconds' -> {topic: period ns}; ParameterError for a malformed entry."""
    out = {}
    for e in entries:
        topic, _, sec = e.rpartition("=")
        try:
            period = float(sec)
        except ValueError:
            period = float("nan")
        if not topic or not (0.0 < period < 3600.0):
            raise ParameterError(f"throttle entries are 'topic=seconds' with 0 < seconds < 3600, got {e!r}")
        out[topic] = int(period * 1e9)
    return out


def main(args=None) -> int:
    return run_node(Recorder, args)


if __name__ == "__main__":
    sys.exit(main())

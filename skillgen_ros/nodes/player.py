"""player node: replay a bag directory or bare .mcap onto topics with the original timing.

Publishes the recorded CDR bytes unchanged (no deserialization) from a dedicated playback
thread, scheduled against a monotonic clock: message i goes out at
t0 + (log_time_i - log_time_first) / rate. Options: start offset into the bag, loop, topic
filter, remapping (`from:=to`), /clock publishing of bag time, and the recorded QoS
(reliability, durability) where the bag has it. Exits when done unless `exit_when_done` is off,
once its subscribers acknowledged every reliable message (at most ACK_TIMEOUT_S): a reader that
matched late gets the resent samples instead of losing them with the exiting process.
A bag that is missing or holds a type this machine lacks stops the node at start with a reason.
"""
from __future__ import annotations

import queue
import sys
import threading
import time
from typing import Iterator

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.duration import Duration
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock

from rclpy.node import Node

from skillgen_ros.core.bag.reader import BagReader, check_installed, message_class, playable_topics
from skillgen_ros.core.errors import ParameterError
from skillgen_ros.nodes.bag_qos import playback_qos
from skillgen_ros.nodes.runtime import run_node


ACK_TIMEOUT_S = 5.0  # per publisher, after the last message, before exit_when_done shuts down


def parse_remaps(pairs: list[str]) -> dict[str, str]:
    """['/a:=/b', ...] -> {'/a': '/b'}; ParameterError on anything else."""
    out = {}
    for pair in pairs:
        if not pair:
            continue
        src, sep, dst = pair.partition(":=")
        if not sep or not src or not dst:
            raise ParameterError(f"remap entry '{pair}' is not 'from:=to'")
        out[src if src.startswith("/") else "/" + src] = dst
    return out


class Player(Node):
    def __init__(self):
        super().__init__("player")
        d = ParameterDescriptor
        self.declare_parameter("bag", "", d(description="bag directory or .mcap file"))
        self.declare_parameter("rate", 1.0, d(description="playback speed factor (2.0 = twice as fast)"))
        self.declare_parameter("start_offset", 0.0, d(description="s into the bag to start from"))
        self.declare_parameter("loop", False, d(description="restart at the end"))
        self.declare_parameter("topics", [""], d(description="only these recorded topics; empty = all"))
        self.declare_parameter("remap", [""], d(description="'from:=to' output topic renames"))
        self.declare_parameter("clock", False, d(description="publish bag time on /clock"))
        self.declare_parameter("clock_frequency", 100.0, d(description="Hz of /clock while playing"))
        self.declare_parameter("delay", 0.5, d(description="s to wait before the first message (discovery)"))
        self.declare_parameter("exit_when_done", True, d(description="shut down after the last message"))
        self.declare_parameter("wait_for_subscribers", 0.0, d(
            description="s to wait (at most) until every played topic has a subscriber; 0 = don't wait"))
        p = {n: self.get_parameter(n).value for n in (
            "bag", "rate", "start_offset", "loop", "topics", "remap", "clock", "clock_frequency", "delay",
            "exit_when_done", "wait_for_subscribers")}
        if not p["bag"]:
            raise ParameterError("parameter 'bag' (a bag directory or .mcap file) is required")
        if p["rate"] <= 0 or p["start_offset"] < 0 or p["delay"] < 0 or p["clock_frequency"] <= 0:
            raise ParameterError("rate > 0, start_offset >= 0, delay >= 0 and clock_frequency > 0 are required")
        self._rate = float(p["rate"])
        self._loop = bool(p["loop"])
        self._delay = float(p["delay"])
        self._exit = bool(p["exit_when_done"])
        self._wait_subs = float(p["wait_for_subscribers"])
        self._reader = BagReader(p["bag"])  # BagError (reason) stops the node with a clear line
        for w in self._reader.warnings:
            self.get_logger().warn(w)
        # Recorded names are absolute; accept 'joint_states' for '/joint_states'.
        topics = [t if t.startswith("/") else "/" + t for t in p["topics"] if t]
        if not topics:  # the whole bag: what this machine can publish (named topics must all be)
            topics, skipped = playable_topics(self._reader)
            if not topics:
                topics = sorted(self._reader.topics)  # nothing playable: check_installed names them all
            elif skipped:
                self.get_logger().warn(f"not replaying (type not installed): {', '.join(skipped)}")
        check_installed(self._reader, topics)  # unknown topic / type not installed -> BagError
        remaps = parse_remaps(p["remap"])
        self._topics = topics
        self._pubs = {}
        for name in topics:
            t = self._reader.topics[name]
            self._pubs[name] = self.create_publisher(message_class(t.type), remaps.get(name, name),
                                                     playback_qos(t.qos_profiles))
        self._start_ns = self._reader.start_ns + int(float(p["start_offset"]) * 1e9)
        self._clock_pub = self.create_publisher(Clock, "/clock", QoSProfile(depth=1)) if p["clock"] else None
        self._bag_now_ns: int | None = None
        if self._clock_pub is not None:
            self.create_timer(1.0 / float(p["clock_frequency"]), self._publish_clock)
        self.published = 0
        self.done = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._play, name="bag-player", daemon=True)
        self._thread.start()

    def _publish_clock(self) -> None:
        if self._bag_now_ns is not None:
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = divmod(self._bag_now_ns, 10**9)
            self._clock_pub.publish(msg)

    def _prefetched(self, max_bytes: int = 256 << 20) -> Iterator:
        """Bag messages read (and decompressed) ahead by a thread, so reading never delays a send."""
        q: queue.Queue = queue.Queue()
        budget = threading.Semaphore(max(1, max_bytes >> 20))  # MiB tokens

        def produce():
            try:
                for m in self._reader.messages(self._topics, start_ns=self._start_ns):
                    need = max(1, len(m.data) >> 20)
                    for _ in range(need):
                        while not budget.acquire(timeout=0.1):
                            if self._stop.is_set():
                                return
                    q.put((m, need))
                q.put((None, 0))
            except Exception as e:  # surfaced in the play thread
                q.put((e, 0))

        threading.Thread(target=produce, name="bag-prefetch", daemon=True).start()
        while True:
            item, need = q.get()
            if item is None:
                return
            if isinstance(item, Exception):
                raise item
            for _ in range(need):
                budget.release()
            yield item

    def _play_once(self) -> None:
        t0 = None
        first = None
        for m in self._prefetched():
            if self._stop.is_set():
                return
            if t0 is None:
                t0, first = time.monotonic(), m.log_time_ns
            due = t0 + (m.log_time_ns - first) / 1e9 / self._rate
            while not self._stop.is_set():
                # Bag time advances with the wall clock between messages (for /clock).
                now = time.monotonic()
                self._bag_now_ns = first + int((now - t0) * self._rate * 1e9)
                if now >= due:
                    break
                self._stop.wait(min(due - now, 0.01))
            self._bag_now_ns = m.log_time_ns
            self._pubs[m.topic].publish(m.data)
            self.published += 1

    def _wait_for_subscribers(self) -> None:
        end = time.monotonic() + self._wait_subs
        while time.monotonic() < end and not self._stop.is_set():
            if all(pub.get_subscription_count() > 0 for pub in self._pubs.values()):
                return
            self._stop.wait(0.02)
        lonely = [n for n, pub in self._pubs.items() if pub.get_subscription_count() == 0]
        self.get_logger().warn(f"no subscribers after {self._wait_subs:.1f} s on {lonely}; playing anyway")

    def _play(self) -> None:
        try:
            if self._wait_subs > 0:
                self._wait_for_subscribers()
            if self._stop.wait(self._delay):
                return
            self.get_logger().info(f"playing {self._reader.path} ({self._reader.message_count} messages, "
                                   f"rate {self._rate})")
            while not self._stop.is_set():
                self._play_once()
                if not self._loop:
                    break
        except Exception as e:  # keep the node's exit clean; say what went wrong
            if self._stop.is_set() or not self.context.ok():
                return  # shutting down under us: nothing to report
            self.get_logger().error(f"playback failed: {type(e).__name__}: {e}")
        self.done.set()
        if not self.context.ok():
            return
        self.get_logger().info(f"playback done: {self.published} messages published")
        if self._exit and not self._stop.is_set():
            ack = Duration(seconds=ACK_TIMEOUT_S)
            unacked = [n for n, pub in self._pubs.items() if not pub.wait_for_all_acked(ack)]
            if unacked:
                self.get_logger().warn(f"exiting with messages not acknowledged on {unacked}")
            self.context.try_shutdown()

    def destroy_node(self):
        self._stop.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout=2.0)
        return super().destroy_node()


def main(args=None) -> int:
    return run_node(Player, args)


if __name__ == "__main__":
    sys.exit(main())

"""Recorder throughput and player timing benchmark.

Input: PointCloud2 640x480 (x, y, z, rgb float32: 4.9 MB each) at 30 Hz plus JointState at 500 Hz
for --duration s (20 s; --quick: 4 s), published by a separate process. Three phases, all on a
private ROS domain, loopback only:
  A. baseline: a null subscriber process (raw subscriptions, counts and timestamps, writes nothing);
  B. the `recorder` node records both topics; we count what reached the bag (goal: 0 lost), the
     bag's MB/s and the recorder's CPU use (user+sys over the recording, in cores);
  C. the `player` node replays the bag; a subscriber here measures each message's timing error
     against the bag's log times (after removing the median latency): p50/p99.
Ratios: recorder vs baseline receive counts and CPU; player timing error vs the live publisher's
own timing error seen by the baseline subscriber.

    python bench/recorder_throughput/run.py [--quick] [--compression lz4|zstd|none] [--qos reliable|sensor]

Writes bench/results/recorder_throughput.json (with the rerun command and machine info).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
from bench.machine import machine_info  # noqa: E402
from skillgen_ros import rosenv  # noqa: E402  (loopback discovery before rclpy)

PC_TOPIC, JS_TOPIC = "/camera/front/points", "/joint_states"
STAMP = struct.Struct("<iI")  # header.stamp right after the 4-byte CDR encapsulation header


def _stamp_of(data: bytes) -> int:
    sec, nsec = STAMP.unpack_from(data, 4)
    return sec * 1_000_000_000 + nsec


def _env(domain: int) -> dict:
    env = rosenv.ros_environment(dict(os.environ))
    env.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", PYTHONUNBUFFERED="1")
    return env


# ---------------------------------------------------------------------------------------------
# child roles
def _cloud_template():
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState, PointCloud2, PointField

    rng = np.random.default_rng(0)
    h, w = 480, 640
    v, u = np.mgrid[0:h, 0:w]
    z = (0.8 + 0.002 * rng.standard_normal((h, w))).astype(np.float32)  # table at 0.8 m + noise
    x = ((u - 320) / 600.0 * z).astype(np.float32)
    y = ((v - 240) / 600.0 * z).astype(np.float32)
    rgb = np.full((h, w), np.float32(0.5), np.float32)
    pts = np.stack([x, y, z, rgb], -1).astype(np.float32)
    fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
              for i, n in enumerate("x y z rgb".split())]
    cloud = PointCloud2(height=h, width=w, fields=fields, is_bigendian=False, point_step=16,
                        row_step=16 * w, is_dense=True)
    cloud.header.frame_id = "front_camera"
    cloud.data = pts.tobytes()
    js = JointState(name=[f"panda_joint{i}" for i in range(1, 8)], position=[0.0] * 7,
                    velocity=[0.0] * 7, effort=[0.0] * 7)
    js.header.frame_id = "base"
    return bytearray(serialize_message(cloud)), bytearray(serialize_message(js))


def role_publisher(a) -> None:
    """Publish both streams on schedule; header.stamp = scheduled send time (CLOCK_MONOTONIC)."""
    import rclpy
    from rclpy.qos import QoSProfile, qos_profile_sensor_data
    from sensor_msgs.msg import JointState, PointCloud2

    cloud, js = _cloud_template()
    rclpy.init()
    node = rclpy.create_node("bench_publisher")
    # Reliable writers keep ~1 s (clouds) / 2 s (joint states) of history, so a reader that stalls
    # briefly on this 2-core machine catches up instead of the writer overwriting unacked samples.
    pc_qos = QoSProfile(depth=30) if a.reliable else qos_profile_sensor_data
    pc_pub = node.create_publisher(PointCloud2, PC_TOPIC, pc_qos)
    js_pub = node.create_publisher(JointState, JS_TOPIC, QoSProfile(depth=1000))
    end = time.monotonic() + 30
    while time.monotonic() < end and min(pc_pub.get_subscription_count(), js_pub.get_subscription_count()) < 1:
        time.sleep(0.05)
    time.sleep(1.0)
    periods = {"pc": 1e9 / 30, "js": 1e9 / 500}
    start = time.monotonic_ns() + 10_000_000
    nxt = {"pc": start, "js": start}
    stop = start + int(a.duration * 1e9)
    counts = {"pc": 0, "js": 0}
    late = []
    while True:
        kind = min(nxt, key=nxt.get)
        due = nxt[kind]
        if due >= stop:
            break
        now = time.monotonic_ns()
        if due > now:
            time.sleep((due - now) / 1e9)
        late.append(time.monotonic_ns() - due)
        buf, pub = (cloud, pc_pub) if kind == "pc" else (js, js_pub)
        STAMP.pack_into(buf, 4, due // 1_000_000_000, due % 1_000_000_000)
        pub.publish(bytes(buf))
        counts[kind] += 1
        nxt[kind] = start + int((counts[kind]) * periods[kind])
    print(json.dumps({"published": {PC_TOPIC: counts["pc"], JS_TOPIC: counts["js"]},
                      "pc_bytes": len(cloud), "js_bytes": len(js),
                      "publisher_late_p99_ms": float(np.percentile(late, 99) / 1e6)}), flush=True)
    if a.reliable:  # a reliable writer destroyed with unacked samples drops them: wait for the acks
        from rclpy.duration import Duration

        for p in (pc_pub, js_pub):
            p.wait_for_all_acked(Duration(seconds=15))
    time.sleep(0.5)
    node.destroy_node()
    rclpy.shutdown()


class _Arrivals:
    """Raw subscriptions to both topics that keep (stamp, arrival CLOCK_MONOTONIC ns)."""

    def __init__(self, node, reliable_pc: bool):
        from rclpy.qos import QoSProfile, qos_profile_sensor_data
        from sensor_msgs.msg import JointState, PointCloud2

        self.items = {PC_TOPIC: [], JS_TOPIC: []}
        pc_qos = QoSProfile(depth=100) if reliable_pc else qos_profile_sensor_data
        node.create_subscription(PointCloud2, PC_TOPIC, lambda d: self._add(PC_TOPIC, d), pc_qos, raw=True)
        node.create_subscription(JointState, JS_TOPIC, lambda d: self._add(JS_TOPIC, d),
                                 QoSProfile(depth=1000), raw=True)

    def _add(self, topic: str, data: bytes) -> None:
        self.items[topic].append((_stamp_of(data), time.monotonic_ns()))


def role_null(a) -> None:
    """Baseline subscriber: receive raw, write nothing; on SIGINT print counts and timing error."""
    import rclpy
    from rclpy.executors import ExternalShutdownException

    rclpy.init()
    node = rclpy.create_node("bench_null")
    arr = _Arrivals(node, a.reliable)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    out = {"received": {t: len(v) for t, v in arr.items.items()},
           "timing_error_ms": {t: _timing_error(v) for t, v in arr.items.items()}}
    print(json.dumps(out), flush=True)


def _timing_error(pairs, reference: dict[int, int] | None = None) -> dict:
    """|arrival - scheduled| after removing the median offset; scheduled = stamp or bag log time."""
    if len(pairs) < 2:
        return {"p50": None, "p99": None, "n": len(pairs)}
    sched = np.array([reference[s] if reference else s for s, _ in pairs if not reference or s in reference],
                     dtype=np.int64)
    arr = np.array([t for s, t in pairs if not reference or s in reference], dtype=np.int64)
    d = (arr - sched).astype(np.float64)
    err = np.abs(d - np.median(d)) / 1e6
    return {"p50": round(float(np.percentile(err, 50)), 3), "p99": round(float(np.percentile(err, 99)), 3),
            "n": int(len(err))}


# ---------------------------------------------------------------------------------------------
# orchestration
def _spawn(cmd, env) -> subprocess.Popen:
    return subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=REPO)


def _stop(proc: subprocess.Popen, timeout: float = 60) -> tuple[str, float]:
    """SIGINT, wait; returns (output, CPU seconds user+sys over the process lifetime)."""
    proc.send_signal(signal.SIGINT)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        pid, status, ru = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            proc.returncode = os.waitstatus_to_exitcode(status)
            return proc.stdout.read(), ru.ru_utime + ru.ru_stime
        time.sleep(0.05)
    proc.kill()
    _, status, ru = os.wait4(proc.pid, 0)
    return proc.stdout.read(), ru.ru_utime + ru.ru_stime


def _last_json(text: str) -> dict:
    for line in reversed(text.splitlines()):
        if line.startswith("{"):
            return json.loads(line)
    raise RuntimeError(f"no JSON in output:\n{text[-2000:]}")


def _cpu_now(pid: int) -> float:
    import psutil

    t = psutil.Process(pid).cpu_times()
    return t.user + t.system


def _phase(subscriber_cmd, env, a) -> tuple[dict, str, float, float]:
    sub = _spawn(subscriber_cmd, env)
    time.sleep(1.0)
    pub = _spawn([sys.executable, __file__, "--role", "publisher", "--duration", str(a.duration)]
                 + ["--qos", a.qos], env)
    time.sleep(1.0)
    cpu0 = _cpu_now(sub.pid)
    t0 = time.monotonic()
    pub_out, _ = pub.communicate(timeout=a.duration + 120)
    published = _last_json(pub_out)
    time.sleep(1.0)  # let the subscriber drain
    wall = time.monotonic() - t0
    out, cpu = _stop(sub)
    return published, out, cpu - cpu0, wall


def _play_phase(bag: Path, env, a) -> dict:
    import rclpy

    from skillgen_ros.core.bag.reader import BagReader

    reference = {_stamp_of(m.data): m.log_time_ns for m in BagReader(bag).messages()}
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=int(env["ROS_DOMAIN_ID"]))
    node = rclpy.create_node("bench_play_probe", context=ctx)
    arr = _Arrivals(node, a.reliable)
    from rclpy.executors import SingleThreadedExecutor

    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    spin = threading.Thread(target=ex.spin, daemon=True)
    spin.start()
    player = _spawn([str(Path(sys.prefix) / "bin" / "player"), "--ros-args", "--params-file",
                     str(REPO / "params" / "player.yaml"), "-p", f"bag:={bag}",
                     "-p", "wait_for_subscribers:=20.0", "-p", "delay:=1.0"], env)
    out, _ = player.communicate(timeout=a.duration * 3 + 120)
    time.sleep(0.5)
    ex.shutdown()
    node.destroy_node()
    rclpy.shutdown(context=ctx)
    return {"received": {t: len(v) for t, v in arr.items.items()},
            "timing_error_ms": {t: _timing_error(v, reference) for t, v in arr.items.items()},
            "player_exit": player.returncode, "player_tail": out[-300:]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="4 s instead of 20 s")
    ap.add_argument("--duration", type=float, default=None)
    ap.add_argument("--compression", default="lz4", choices=["zstd", "lz4", "none"],
                    help="recorder chunk compression (lz4 is the recorder's default)")
    ap.add_argument("--qos", choices=["reliable", "sensor"], default="reliable",
                    help="point cloud QoS: reliable (default; isolates the recorder from transport loss) or "
                         "sensor data (best effort: Fast DDS drops most 4.9 MB samples even for a null subscriber)")
    ap.add_argument("--role", choices=["publisher", "null"], help=argparse.SUPPRESS)
    ap.add_argument("--out", default=str(REPO / "bench" / "results" / "recorder_throughput.json"))
    a = ap.parse_args()
    a.reliable = a.qos == "reliable"
    a.duration = a.duration or (4.0 if a.quick else 20.0)
    if a.role == "publisher":
        role_publisher(a)
        return 0
    if a.role == "null":
        role_null(a)
        return 0

    load_before = os.getloadavg()
    env = _env(domain=60 + os.getpid() % 30)
    os.environ.update(env)
    tmp = Path(tempfile.mkdtemp(prefix="recbench_"))
    try:
        # A: baseline null subscriber
        published_a, out_a, cpu_a, wall_a = _phase(
            [sys.executable, __file__, "--role", "null"] + ["--qos", a.qos], env, a)
        base = _last_json(out_a)
        # B: recorder
        bag = tmp / "bench_bag"
        rec_cmd = [str(Path(sys.prefix) / "bin" / "recorder"), "--ros-args", "--params-file",
                   str(REPO / "params" / "recorder.yaml"), "-p", f"output:={bag}",
                   "-p", f"topics:=[{PC_TOPIC}, {JS_TOPIC}]", "-p", f"compression:={a.compression}"]
        published_b, out_b, cpu_b, wall_b = _phase(rec_cmd, env, a)
        from skillgen_ros.core.bag.info import bag_info

        info = bag_info(bag)
        recorded = {t.name: t.message_count for t in info.topics}
        lost = {t: published_b["published"][t] - recorded.get(t, 0) for t in (PC_TOPIC, JS_TOPIC)}
        payload_mb = (published_b["published"][PC_TOPIC] * published_b["pc_bytes"]
                      + published_b["published"][JS_TOPIC] * published_b["js_bytes"]) / 1e6
        # C: player
        play = _play_phase(bag, env, a)
    finally:
        bag_bytes = sum(p.stat().st_size for p in tmp.rglob("*") if p.is_file())
        shutil.rmtree(tmp, ignore_errors=True)

    base_lost = {t: published_a["published"][t] - base["received"][t] for t in (PC_TOPIC, JS_TOPIC)}
    result = {
        "benchmark": "recorder_throughput",
        "command": " ".join(["python", "bench/recorder_throughput/run.py"] + sys.argv[1:]),
        "machine": machine_info(
            loadavg_1m_before_after=[round(load_before[0], 2), round(os.getloadavg()[0], 2)],
            note="shared machine: other jobs' load inflates losses and timing errors"),
        "input": {"duration_s": a.duration, "pointcloud": "640x480 xyz+rgb float32 @30 Hz",
                  "pointcloud_bytes": published_b["pc_bytes"], "joint_states_hz": 500,
                  "pointcloud_qos": "reliable" if a.reliable else "sensor_data (best effort)",
                  "compression": a.compression},
        "recorder": {
            "published": published_b["published"], "recorded": recorded, "lost": lost,
            "lost_total": sum(lost.values()),
            "bag_bytes": bag_bytes, "bag_mb_per_s": round(bag_bytes / 1e6 / a.duration, 2),
            "payload_mb_per_s": round(payload_mb / a.duration, 2),
            "cpu_cores": round(cpu_b / wall_b, 3), "cpu_seconds": round(cpu_b, 2),
            "publisher_late_p99_ms": published_b["publisher_late_p99_ms"]},
        "baseline_null_subscriber": {
            "published": published_a["published"], "received": base["received"], "lost": base_lost,
            "cpu_cores": round(cpu_a / wall_a, 3), "timing_error_ms": base["timing_error_ms"]},
        "player": play,
        "ratios": {
            "recorder_vs_baseline_cpu": round(cpu_b / max(cpu_a, 1e-9), 2),
            "recorder_vs_baseline_received": {
                t: round(recorded.get(t, 0) / max(base["received"][t], 1), 4) for t in (PC_TOPIC, JS_TOPIC)},
            "player_vs_live_publisher_p99_timing_error": {
                t: (round(play["timing_error_ms"][t]["p99"] / max(base["timing_error_ms"][t]["p99"], 1e-6), 2)
                    if play["timing_error_ms"][t]["p99"] is not None and base["timing_error_ms"][t]["p99"]
                    else None) for t in (PC_TOPIC, JS_TOPIC)},
        },
    }
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())

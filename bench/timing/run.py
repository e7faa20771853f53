"""Wall-clock figures moved out of the test suite (issue 19): on a shared CI machine they measure
the load, not the code, so the suite asserts counts and orders and this script reports the rates.

  driver_realtime_hz   sim_driver in realtime mode: ee_pose messages per wall second (goal 20)
  lockstep_timeout_hz  sim_driver in lockstep with no commands: periods per wall second (goal 1 /
                       lockstep_timeout_s = 4 at 0.25 s)
  player timing error  is bench/recorder_throughput/run.py's phase C (p50/p99 against the bag).

    PYTHONPATH=$PWD python bench/timing/run.py [--seconds 5]

Writes bench/results/timing.json (with the command and machine info).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
from bench.machine import machine_info  # noqa: E402
from skillgen_ros import rosenv  # noqa: E402,F401  (loopback discovery before rclpy)


def _measure(domain: int, params: list[str], topic_type: str, seconds: float) -> dict:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    env = rosenv.node_environment(dict(os.environ))
    env["ROS_DOMAIN_ID"] = str(domain)
    log = tempfile.TemporaryFile()
    proc = subprocess.Popen([str(Path(sys.prefix) / "bin" / "sim_driver"), "--ros-args", "-p", "camera_hz:=0.0",
                             *params], env=env, stdout=log, stderr=subprocess.STDOUT)
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    try:
        node = rclpy.create_node("timing_bench", context=ctx)
        arrivals: list[float] = []
        if topic_type == "clock":
            from rosgraph_msgs.msg import Clock
            node.create_subscription(Clock, "/clock", lambda _m: arrivals.append(time.monotonic()), 100)
        else:
            from geometry_msgs.msg import PoseStamped
            node.create_subscription(PoseStamped, "ee_pose", lambda _m: arrivals.append(time.monotonic()), 100)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        threading.Thread(target=ex.spin, daemon=True).start()
        end = time.monotonic() + 60
        while len(arrivals) < 2 and time.monotonic() < end:
            time.sleep(0.05)
        start_n, t0 = len(arrivals), time.monotonic()
        time.sleep(seconds)  # a measurement window, not synchronisation
        n, dt = len(arrivals) - start_n, time.monotonic() - t0
        ex.shutdown()
        return {"messages": n, "seconds": round(dt, 3), "hz": round(n / dt, 2)}
    finally:
        rclpy.shutdown(context=ctx)
        proc.send_signal(2)
        proc.wait(20)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--domain", type=int, default=97)
    a = ap.parse_args()
    out = {
        "command": "PYTHONPATH=$PWD python bench/timing/run.py " + " ".join(sys.argv[1:]),
        "machine": machine_info(),
        "driver_realtime_hz": {"goal": 20.0, **_measure(a.domain, ["-p", "timing_mode:=realtime",
                                                                    "-p", "initial_task:=Square"], "ee", a.seconds)},
        "lockstep_timeout_hz": {"goal": 4.0, **_measure(a.domain, ["-p", "lockstep_timeout_s:=0.25"], "clock",
                                                        a.seconds)},
    }
    path = REPO / "bench" / "results" / "timing.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps({k: v for k, v in out.items() if k != "machine"}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Benchmark of the simulated Panda driver (issue 3).

Reports, in one run:
- real-time factor (sim seconds per wall second) in lockstep, in-process and through the
  sim_driver node over ROS 2, with no cameras and with two 84x84 cameras at 20 Hz;
- OSC tracking error (mean / max, mm and deg) on a figure-eight at 20 Hz: after each control
  period, the distance between the EE and that period's target;
- overhead ratio = wall time of the same command sequence over ROS 2 topics in lockstep (client
  sends a target, waits for the resulting ee_pose, sends the next) / wall time stepping the same
  sim in-process. Goal: <= 1.5. Also the same ratio in CPU seconds (driver + client processes vs
  the in-process run), which a loaded machine's scheduling delays do not inflate.
- scripted-solution success rate over a few seeds per task/variant (the privileged solver).
Writes bench/results/sim_driver.json.  Usage: python bench/sim_driver/run.py [--quick]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
from bench.machine import machine_info  # noqa: E402

from skillgen_ros import rosenv  # noqa: E402
from skillgen_ros.core.geometry import Pose, rotation_angle  # noqa: E402
from skillgen_ros.core.sim import SimWorld  # noqa: E402
from skillgen_ros.core.sim.camera import CameraConfig  # noqa: E402
from skillgen_ros.core.tasks import TASK_NAMES, get_task, scripted  # noqa: E402

HZ = 20.0
CAMS = (CameraConfig("front", 84, 84), CameraConfig("wrist", 84, 84))


def figure_eight(n: int, center=(0.50, 0.0, 0.25), amp=(0.10, 0.12), period_s=8.0, yaw_amp_deg=20.0):
    """Targets along a lemniscate in the horizontal plane with a yaw oscillation."""
    t = np.arange(1, n + 1) / HZ
    w = 2 * np.pi / period_s
    base = Rotation.from_euler("x", np.pi)
    out = []
    for tk in t:
        p = np.array(center) + [amp[0] * np.sin(w * tk), amp[1] * np.sin(2 * w * tk) / 2, 0.03 * np.sin(w * tk)]
        yaw = np.radians(yaw_amp_deg) * np.sin(w * tk)
        out.append(Pose(p, (Rotation.from_euler("z", yaw) * base).as_quat()))
    return out


def lead_in(world: SimWorld, first: Pose, periods: int = 40) -> None:
    start = world.ee_pose()
    for k in range(1, periods + 1):
        s = k / periods
        world.step(Pose(start.position + s * (first.position - start.position), first.quaternion), -1.0)


def in_process(targets, cameras: bool) -> dict:
    world = SimWorld(cameras=CAMS if cameras else ())
    world.reset("Square", "D0", 0)
    lead_in(world, targets[0])
    pos_err, ang_err, ee_pos = [], [], []
    c0 = time.process_time()
    t0 = time.perf_counter()
    for tgt in targets:
        world.step(tgt, -1.0)
        if cameras:
            world.render("front"), world.render("wrist")
        ee = world.ee_pose()
        ee_pos.append(ee.position)
        pos_err.append(np.linalg.norm(ee.position - tgt.position))
        ang_err.append(rotation_angle(ee.rotation.as_matrix(), tgt.rotation.as_matrix()))
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    world.close()
    sim = len(targets) / HZ
    # OSC without feed-forward lags a moving target; the error against the target `lag` periods
    # earlier separates that delay from shape error
    tp, ep = np.array([t.position for t in targets]), np.array(ee_pos)
    lagged = {lag: 1e3 * float(np.mean(np.linalg.norm(ep[lag:] - tp[:len(tp) - lag], axis=1))) for lag in range(6)}
    best = min(lagged, key=lagged.get)
    return {"wall_s": wall, "cpu_s": cpu, "sim_s": sim, "rtf": sim / wall,
            "pos_err_mm": {"mean": 1e3 * float(np.mean(pos_err)), "max": 1e3 * float(np.max(pos_err))},
            "ang_err_deg": {"mean": float(np.degrees(np.mean(ang_err))), "max": float(np.degrees(np.max(ang_err)))},
            "pos_err_mm_best_lag": {"lag_periods": best, "mean": lagged[best]}}


def over_ros(targets, cameras: bool, domain: int) -> dict:
    """Drive sim_driver (lockstep) over topics: send a target, wait for its ee_pose, repeat."""
    env = rosenv.ros_environment(dict(os.environ))
    env.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    cmd = [str(Path(sys.prefix) / "bin" / "sim_driver"), "--ros-args", "--params-file",
           str(REPO / "params" / "sim_driver.yaml"), "-p", "timing_mode:=lockstep", "-p", "initial_task:=Square",
           "-p", "lockstep_timeout_s:=30.0", "-p", f"camera_hz:={20.0 if cameras else 0.0}",
           "-p", "front_width:=84", "-p", "front_height:=84", "-p", "wrist_width:=84", "-p", "wrist_height:=84",
           "-p", "publish_points:=true"]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from skillgen_interfaces.msg import OscTarget
    from skillgen_ros.nodes.convert import pose_to_msg

    rclpy.init()
    node = rclpy.create_node("sim_driver_bench")
    got: list = []
    from rclpy.event_handler import SubscriptionEventCallbacks
    node.create_subscription(PoseStamped, "ee_pose", lambda m: got.append(m), 10,
                             event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
    pub = node.create_publisher(OscTarget, "osc_target", 10)
    # A camera consumer, as perception is in the graph: the driver renders and publishes a camera
    # only while its topics have readers. Read on demand, so the client itself is not woken per frame.
    clouds = {}
    if cameras:
        from rclpy.qos import qos_profile_sensor_data
        from sensor_msgs.msg import PointCloud2
        from skillgen_ros.nodes.latest import LatestMessage
        clouds = {n: LatestMessage(node, PointCloud2, f"camera/{n}/points", qos_profile_sensor_data)
                  for n in ("front", "wrist")}
    exe = rclpy.executors.SingleThreadedExecutor()
    exe.add_node(node)
    try:
        deadline = time.monotonic() + 30
        while (pub.get_subscription_count() == 0 or node.count_publishers("ee_pose") == 0
               or any(node.count_publishers(f"camera/{n}/points") == 0 for n in clouds)):
            exe.spin_once(timeout_sec=0.05)
            if time.monotonic() > deadline:
                raise RuntimeError("sim_driver did not come up")
        time.sleep(0.5)

        def send_and_wait(pose: Pose):
            n = len(got)
            pub.publish(OscTarget(pose=pose_to_msg(pose), gripper=-1.0))
            while len(got) <= n:
                exe.spin_once(timeout_sec=1.0)

        start = Pose(np.array([0.46348, 0.0, 0.40119]), np.array([1.0, 0.0, 0.0, 0.0]))
        for k in range(1, 41):  # the same lead-in as in-process
            s = k / 40
            send_and_wait(Pose(start.position + s * (targets[0].position - start.position), targets[0].quaternion))
        c0, d0 = time.process_time(), _cpu_seconds(proc.pid)
        t0 = time.perf_counter()
        for tgt in targets:
            send_and_wait(tgt)
        wall = time.perf_counter() - t0
        cpu = time.process_time() - c0 + _cpu_seconds(proc.pid) - d0
        frames = {n: c.latest(timeout=2.0) for n, c in clouds.items()}
        if any(f is None for f in frames.values()):
            raise RuntimeError(f"no camera frames arrived: {frames}")
    finally:
        for c in clouds.values():
            c.destroy()
        exe.shutdown()
        node.destroy_node()
        rclpy.shutdown()
        proc.send_signal(2)
        proc.wait(10)
    sim = len(targets) / HZ
    return {"wall_s": wall, "cpu_s": cpu, "sim_s": sim, "rtf": sim / wall}


def _cpu_seconds(pid: int) -> float:
    """user + system CPU seconds of a process (all its threads)."""
    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def mock_startup(runs: int = 5) -> dict:
    """mock_driver from spawn to its "up" log line: wall and CPU seconds (goal: under 1 s)."""
    import select

    env = rosenv.ros_environment(dict(os.environ))
    env.update(ROS_DOMAIN_ID=str(90 + os.getpid() % 9), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               PYTHONUNBUFFERED="1")
    cmd = [str(Path(sys.prefix) / "bin" / "mock_driver"), "--ros-args", "--params-file",
           str(REPO / "params" / "mock_driver.yaml")]
    wall, cpu = [], []
    for _ in range(runs):
        t0 = time.monotonic()
        proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        try:
            while time.monotonic() - t0 < 20.0:
                if select.select([proc.stdout], [], [], 0.1)[0] and "mock_driver up" in proc.stdout.readline():
                    wall.append(time.monotonic() - t0)
                    cpu.append(_cpu_seconds(proc.pid))
                    break
        finally:
            proc.send_signal(2)
            proc.wait(10)
    return {"runs": runs, "up": len(wall), "wall_s_median": float(np.median(wall)) if wall else None,
            "cpu_s_median": float(np.median(cpu)) if cpu else None, "wall_s_all": wall, "cpu_s_all": cpu,
            "goal_s": 1.0}


def scripted_rates(seeds: int) -> dict:
    world = SimWorld()
    out = {}
    for t in TASK_NAMES:
        for v in get_task(t).variants:
            ok = 0
            for s in range(seeds):
                world.reset(t, v, s)
                ok += scripted.solve(world).success
            out[f"{t}/{v}"] = {"success": ok, "seeds": seeds}
    world.close()
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter figure-eight, 2 seeds per variant")
    ap.add_argument("--repeats", type=int, default=None, help="runs of each timing (default 5, quick 1); the best of them is reported")
    ap.add_argument("--out", default=str(REPO / "bench" / "results" / "sim_driver.json"))
    args = ap.parse_args()
    n = 160 if args.quick else 400
    seeds = 2 if args.quick else 5
    args.repeats = args.repeats or (1 if args.quick else 5)
    targets = figure_eight(n)
    res = {"command": " ".join(["python", "bench/sim_driver/run.py"] + (["--quick"] if args.quick else [])),
           "machine": machine_info(loadavg_start=os.getloadavg()),
           "setup": {"control_hz": HZ, "physics_hz": 240.0, "periods": n, "cameras": "front+wrist 84x84 at 20 Hz",
                     "figure_eight": "x amp 0.10 m, y amp 0.06 m, z 0.03 m, yaw +-20 deg, period 8 s"}}
    dom = 60 + os.getpid() % 30
    # alternate in-process and ROS runs and keep each one's fastest: the machine may be shared
    runs: dict[str, list] = {k: [] for k in ("in_process_no_cameras", "in_process_cameras",
                                             "ros_lockstep_no_cameras", "ros_lockstep_cameras")}
    for _ in range(args.repeats):
        runs["in_process_no_cameras"].append(in_process(targets, False))
        runs["ros_lockstep_no_cameras"].append(over_ros(targets, False, dom))
        runs["in_process_cameras"].append(in_process(targets, True))
        runs["ros_lockstep_cameras"].append(over_ros(targets, True, dom))
    for k, v in runs.items():
        res[k] = min(v, key=lambda r: r["wall_s"])
        res[k]["wall_s_all"] = [r["wall_s"] for r in v]
    res["osc_tracking"] = {k: res["in_process_no_cameras"][k] for k in ("pos_err_mm", "ang_err_deg",
                                                                        "pos_err_mm_best_lag")}
    res["overhead_ratio_no_cameras"] = res["ros_lockstep_no_cameras"]["wall_s"] / res["in_process_no_cameras"]["wall_s"]
    res["overhead_ratio_cameras"] = res["ros_lockstep_cameras"]["wall_s"] / res["in_process_cameras"]["wall_s"]
    # the same, as the median over back-to-back (in-process, ROS) pairs: less sensitive to one lucky run
    for k in ("no_cameras", "cameras"):
        pairs = [r["wall_s"] / i["wall_s"] for i, r in zip(runs[f"in_process_{k}"], runs[f"ros_lockstep_{k}"])]
        res[f"overhead_ratio_paired_median_{k}"] = float(np.median(pairs))
        res[f"overhead_ratio_pairs_{k}"] = pairs
    # CPU-time ratio (driver + client vs in-process): the graph's cost without the scheduler delays a
    # shared, loaded machine adds to every lockstep round trip
    res["overhead_ratio_cpu_no_cameras"] = res["ros_lockstep_no_cameras"]["cpu_s"] / res["in_process_no_cameras"]["cpu_s"]
    res["overhead_ratio_cpu_cameras"] = res["ros_lockstep_cameras"]["cpu_s"] / res["in_process_cameras"]["cpu_s"]
    res["graph_overhead_ms_per_period"] = {
        k: 1e3 * (res[f"ros_lockstep_{k}"]["wall_s"] - res[f"in_process_{k}"]["wall_s"]) / n
        for k in ("no_cameras", "cameras")}
    res["overhead_goal"] = 1.5
    res["notes"] = ("wall-time ratios are only meaningful on an otherwise idle machine (compare loadavg); "
                    "on a shared one the CPU-time ratios measure the graph's cost")
    res["mock_driver_startup"] = mock_startup()
    res["scripted_success"] = scripted_rates(seeds)
    res["machine"]["loadavg_end"] = os.getloadavg()
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(res, indent=2))
    print(json.dumps({k: v for k, v in res.items() if k != "scripted_success"}, indent=2))
    print("scripted success:", {k: f"{v['success']}/{v['seeds']}" for k, v in res["scripted_success"].items()})
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""bench/datagen/observation_truth.py: an independent check of a graph run's recorded object poses.

A listener on `joint_states` and `sim/ground_truth/object_poses` runs while `skillgen generate`
(the datagen graph, Square D0) writes its dataset; each recorded row is matched to the period whose
joint_states carried exactly its joint positions (rows whose joints occur in more than one period,
e.g. the home pose, are skipped) and compared with that period's ground truth. The listener adds
two readers to the control loop, so time this run for nothing else.

    .venv/bin/python bench/datagen/observation_truth.py --attempts 3 --seed 5 --domain 97
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--attempts", type=int, default=3)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--domain", type=int, default=97)
    a = ap.parse_args(argv)
    os.environ["ROS_DOMAIN_ID"] = str(a.domain)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    import rclpy
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    from skillgen_interfaces.msg import ObjectPoseArray

    rclpy.init()
    node = rclpy.create_node("observation_truth")
    joints, truth = {}, {}

    def ns(s):
        return s.sec * 10**9 + s.nanosec

    def on_truth(m):
        truth[ns(m.header.stamp)] = {o.id: np.array([o.pose.position.x, o.pose.position.y, o.pose.position.z,
                                                     o.pose.orientation.x, o.pose.orientation.y, o.pose.orientation.z,
                                                     o.pose.orientation.w]) for o in m.objects}
    node.create_subscription(JointState, "joint_states",
                             lambda m: joints.setdefault(np.array(m.position[:7]).tobytes(), []).append(ns(m.header.stamp)),
                             QoSProfile(depth=1000))
    node.create_subscription(ObjectPoseArray, "sim/ground_truth/object_poses", on_truth,
                             QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                                        durability=DurabilityPolicy.TRANSIENT_LOCAL))
    ex = rclpy.executors.MultiThreadedExecutor()
    ex.add_node(node)
    threading.Thread(target=ex.spin, daemon=True).start()
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "run")
        p = subprocess.run([str(ROOT / ".venv" / "bin" / "skillgen"), "generate", "--task", "Square", "--variant", "D0",
                            "--attempts", str(a.attempts), "--seed", str(a.seed), "--output", out, "--no-bag",
                            "--video-attempts", "0"], cwd=ROOT, capture_output=True, text=True)
        if p.returncode != 0:
            print(p.stdout[-800:], p.stderr[-800:], file=sys.stderr)
            return 1
        pos_err, rot_err, matched, skipped = [], [], 0, 0
        for name in ("demo.hdf5", "failed.hdf5"):
            with h5py.File(os.path.join(out, name), "r") as f:
                for d in f["data"].values():
                    q = d["obs/robot0_joint_pos"][()]
                    ids = [k[:-5] for k in d["obs"] if k.endswith("_pose")]
                    for t in range(len(q)):
                        stamps = joints.get(q[t].tobytes(), [])
                        if len(stamps) != 1 or stamps[0] not in truth:
                            skipped += 1
                            continue
                        matched += 1
                        for oid in ids:
                            rec, true = d[f"obs/{oid}_pose"][t], truth[stamps[0]][oid]
                            pos_err.append(np.linalg.norm(rec[:3] - true[:3]))
                            rot_err.append(min(np.linalg.norm(rec[3:] - true[3:]), np.linalg.norm(rec[3:] + true[3:])))
    ex.shutdown()
    rclpy.shutdown()
    print(f"rows matched {matched}, skipped {skipped}; max |recorded - true| position {max(pos_err, default=np.nan):.2e} m, "
          f"quaternion {max(rot_err, default=np.nan):.2e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The MimicGen baseline's Square attempts run in MuJoCo (robosuite 1.5.2) beside pybullet: same algorithm.

Why: our MimicGen baseline succeeds on Square D1/D2 far more often than the paper's (82 / 70.5% vs 48.9 /
31.8%, README gap table); its failures here are nuts slipping in the hand, and the suspicion is that
pybullet keeps grasps through contacts MuJoCo breaks. This runs *the same attempts* (run seed, index:
same scene, same source demo choice, offsets and action noise; core/generation/mimicgen.py unchanged)
with robosuite's NutAssemblySquare as the world: its Panda, OSC_POSE controller (robosuite's defaults:
kp 150, output_max 0.05 m / 0.5 rad, 20 Hz), gripper, nut and peg, and its own success check
(`NutAssembly._check_success`: on_peg and r_reach < 0.6), read at every step as MimicGen does.

What differs from the paper's MimicGen: the source demos are ours (scripted, recorded in pybullet), and
robosuite is 1.5.2 on MuJoCo 3.3.0 where MimicGen used robosuite 1.4.1 on MuJoCo 2.3.2.

Frames: our world is the Panda base (core/robot.py); robosuite's base body sits at (-0.56, 0, 0.912) with
the same orientation (read from the model, checked). Our EE is panda_grasptarget (pinocchio FK); robosuite
acts on `gripper0_right_grip_site`; the constant transform between them is measured by FK at several joint
configurations and must agree to 1e-6 (checked). The two grippers differ below it: pybullet_data's finger
mesh ends 0.72 cm beyond panda_grasptarget, robosuite's finger mesh 0.07 cm beyond the same point (its pads end
0.41 cm short of it), so a target reached as ours leaves robosuite's fingers 0.65 cm higher on the object
(a demo's nut grasp, 0.9 cm into the 2 cm nut in pybullet, closes on air). `--tip-align` (the default) moves
robosuite's grip site that much further along the approach axis, so the fingertips land where ours do;
measured from both models at start. The peg keeps robosuite's body z (its box is 20 cm
tall, centred 3 cm below the top of the table; on_peg reads only its x, y); robosuite's nut body is placed
at our nut's `body_origin` keypoint (the ring centre, 2.75 cm from our nut frame's origin along the handle
axis), handle along +x in both. `--nut ours` puts our nut's boxes and mass there instead (our_nut_xml).
Results and what they mean: docs/tasks.md "MimicGen's Square replays in MuJoCo".

robosuite and MuJoCo are not project dependencies; install them beside the venv, not into it:
    .venv/bin/python -m pip install --target out/mujoco_site --no-deps robosuite==1.5.2 mujoco==3.3.0 \
        numba llvmlite termcolor glfw pyopengl etils absl-py
    PYTHONPATH=$PWD .venv/bin/python bench/datagen/mujoco_crosscheck.py --variants D1 --attempts 40 \
        --out bench/results/mujoco_crosscheck.json
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from skillgen_ros.core.generation.attempt import run_attempt  # noqa: E402
from skillgen_ros.core.generation.episode import Observation  # noqa: E402
from skillgen_ros.core.generation.session import RunRequest  # noqa: E402
from skillgen_ros.core.geometry import Pose  # noqa: E402
from skillgen_ros.core.robot import Q_HOME, TABLE_Z  # noqa: E402
from skillgen_ros.core.skills.actions import pose_to_delta_action  # noqa: E402
from skillgen_ros.core.tasks import get_task  # noqa: E402
from skillgen_ros.core.tasks.objects import square_nut  # noqa: E402

ARM = [f"robot0_joint{i}" for i in range(1, 8)]
FINGERS = ["gripper0_right_finger_joint1", "gripper0_right_finger_joint2"]
NUT_JOINT = "SquareNut_joint0"
ROBOSUITE_GRIPPER_SPEED = 0.2  # models/grippers/panda_gripper.py PandaGripper.speed


def our_nut_xml(path: Path) -> Path:
    """robosuite's square-nut.xml with our nut's boxes and mass (core/tasks/objects.py square_nut) in place of
    its own, keeping its contact parameters (solimp, solref, friction, condim) and sites: the same object in
    both engines. The body frame is the ring centre, as robosuite's (on_peg reads it)."""
    nut = square_nut()
    origin = np.asarray(nut.keypoint("body_origin"), float)
    volume = sum(8 * float(np.prod(pt.size)) for pt in nut.parts)
    geoms = []
    for pt in nut.parts:
        if pt.kind != "box":
            raise ValueError(f"square nut part {pt.kind} is not a box")
        x, y, z = np.asarray(pt.position, float) - origin
        qw = np.roll(np.asarray(pt.quaternion, float), 1)
        geoms.append(f'<geom pos="{x:.6f} {y:.6f} {z:.6f}" quat="{" ".join(f"{v:.6f}" for v in qw)}" '
                     f'size="{" ".join(f"{v:.6f}" for v in pt.size)}" type="box" solimp="0.998 0.998 0.001" '
                     f'solref="0.02 1" density="{nut.mass / volume:.3f}" friction="0.95 0.3 0.1" group="0" condim="4"/>')
    handle = np.asarray(nut.keypoint("handle"), float) - origin
    path.write_text(f"""<mujoco model="square-nut">
  <worldbody>
    <body>
      <body name="object">
        {chr(10).join(geoms)}
        <site rgba="1 0 0 1" size="0.005" pos="{handle[0]:.6f} 0 0" name="handle_site"/>
        <site rgba="1 0 0 1" size="0.003" pos="0 0 0" name="center_site"/>
      </body>
      <site rgba="0 0 0 0" size="0.005" pos="0 0 -0.05" name="bottom_site"/>
      <site rgba="0 0 0 0" size="0.005" pos="0 0 0.01" name="top_site"/>
      <site rgba="0 0 0 0" size="0.005" pos="0.11 0.06 0" name="horizontal_radius_site"/>
    </body>
  </worldbody>
</mujoco>
""")
    return path


def _use_nut_xml(path: str | None) -> None:
    """Make robosuite's SquareNutObject load `path` (None: its own square-nut.xml)."""
    from robosuite.models.objects import xml_objects
    from robosuite.utils.mjcf_utils import xml_path_completion

    def init(self, name):
        xml_objects.MujocoXMLObject.__init__(self, path or xml_path_completion("objects/square-nut.xml"), name=name,
                                             joints=[dict(type="free", damping="0.0005")], obj_type="all",
                                             duplicate_collision_geoms=True)
    xml_objects.SquareNutObject.__init__ = init


def _T(pos, xmat) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = np.asarray(xmat).reshape(3, 3), pos
    return T


class RobosuiteSquareEnv:
    """GenerationEnv (core/generation/attempt.py) over robosuite's NutAssemblySquare; MimicGen needs no planner."""

    def __init__(self, pybullet_tip_depth: float | None = None, gripper_speed: float = ROBOSUITE_GRIPPER_SPEED,
                 nut_xml: str | None = None):
        """pybullet_tip_depth: how far our finger mesh reaches beyond panda_grasptarget (m); given, robosuite's
        fingertips are moved to the same depth (see the module docstring); None leaves the grip site as is."""
        import robosuite
        from robosuite.controllers import load_composite_controller_config
        from skillgen_ros.core.planning.kinematics import PandaKinematics

        _use_nut_xml(nut_xml)
        self.env = robosuite.make("NutAssemblySquare", robots="Panda",
                                  controller_configs=load_composite_controller_config(controller="BASIC", robot="Panda"),
                                  has_renderer=False, has_offscreen_renderer=False, use_camera_obs=False,
                                  control_freq=20, ignore_done=True, reward_shaping=False, hard_reset=False,
                                  initialization_noise=None)
        self.env.robots[0].init_qpos = np.array(Q_HOME)
        self._set_gripper_speed(gripper_speed)
        self.env.reset()
        m = self.env.sim.model
        self.site = self.env.robots[0].eef_site_id["right"]
        self.arm = [m.get_joint_qpos_addr(j) for j in ARM]
        self.fingers = [m.get_joint_qpos_addr(j) for j in FINGERS]
        self.peg = m.body_name2id("peg1")
        d = self.env.sim.data
        base = m.body_name2id("robot0_base")
        R = d.body_xmat[base].reshape(3, 3)
        if not np.allclose(R, np.eye(3), atol=1e-9):
            raise RuntimeError(f"robosuite's base is turned: {R}")
        self.offset = np.array(d.body_xpos[base])  # our world (the base) in robosuite's
        self.kin = PandaKinematics()
        self.C = self._ee_offset()
        self._set_q(Q_HOME)
        self.mj_tip_depth = self._tip_depth()
        self.tip_shift = 0.0 if pybullet_tip_depth is None else float(pybullet_tip_depth) - self.mj_tip_depth
        Tz = np.eye(4)
        Tz[2, 3] = -self.tip_shift
        self.C = Tz @ self.C  # ee = site @ C: the site sits tip_shift further along the approach for the same ee
        self.peg_z = float(m.body_pos[self.peg][2])
        self.nut_mass = float(m._model.body_subtreemass[m.body_name2id("SquareNut_main")])
        self.nut_origin = np.asarray(square_nut().keypoint("body_origin"), float)
        self.scene_poses: dict[str, Pose] = {}

    def _set_gripper_speed(self, speed: float) -> None:
        """robosuite's PandaGripper moves its command by `speed` a step (0.2: closed in 10 steps); ours
        closes at once (2.0 does too). A property on the class, read per instance here."""
        from robosuite.models.grippers.panda_gripper import PandaGripper

        if not getattr(PandaGripper, "_speed_patched", False):
            PandaGripper.speed = property(lambda g: getattr(g, "_speed", ROBOSUITE_GRIPPER_SPEED))
            PandaGripper._speed_patched = True
        self.env.robots[0].gripper["right"]._speed = float(speed)
        self.gripper_speed = float(speed)

    def _site(self) -> np.ndarray:
        d = self.env.sim.data
        T = _T(d.site_xpos[self.site], d.site_xmat[self.site])
        T[:3, 3] -= self.offset
        return T

    def _set_q(self, q) -> None:
        d = self.env.sim.data
        for a, v in zip(self.arm, q):
            d.qpos[a] = v
        self.env.sim.forward()

    def _ee_offset(self) -> np.ndarray:
        """T_site^{ee}: the same at every configuration if both arms are the same Panda (checked)."""
        rng = np.random.default_rng(0)
        Cs = []
        for k in range(4):
            q = np.array(Q_HOME) + (0 if k == 0 else rng.uniform(-0.4, 0.4, 7))
            self._set_q(q)
            Cs.append(np.linalg.inv(self._site()) @ self.kin.fk(q))
        if max(np.abs(c - Cs[0]).max() for c in Cs) > 1e-6:
            raise RuntimeError(f"grip site to panda_grasptarget is not constant: {Cs}")
        return Cs[0]

    def _tip_depth(self) -> float:
        """How far robosuite's finger mesh reaches beyond the ee point along the approach (m), at Q_HOME."""
        import mujoco

        m, d = self.env.sim.model._model, self.env.sim.data._data
        T = self._site() @ self.C
        lowest = np.inf
        for g in range(m.ngeom):
            if mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) in ("gripper0_right_finger1_collision",
                                                                     "gripper0_right_finger2_collision"):
                a, n = m.mesh_vertadr[m.geom_dataid[g]], m.mesh_vertnum[m.geom_dataid[g]]
                V = m.mesh_vert[a:a + n] @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g] - self.offset
                lowest = min(lowest, float(((V - T[:3, 3]) @ T[:3, 2]).max()))
        return lowest

    # -- GenerationEnv
    def reset(self, task: str, variant: str, seed: int):
        poses = get_task(task).sample_reset(variant, np.random.default_rng(seed))  # as sim/world.py samples
        self.env.reset()
        sim = self.env.sim
        peg = poses["square_peg"]
        sim.model.body_pos[self.peg] = [*(peg.position[:2] + self.offset[:2]), self.peg_z]
        sim.model.body_quat[self.peg] = np.roll(peg.rotation.as_quat(), 1)
        nut = poses["square_nut"]  # our nut frame; robosuite's body sits at our body_origin keypoint (ring centre)
        body = nut.rotation.apply(self.nut_origin) + nut.position + self.offset
        sim.data.set_joint_qpos(NUT_JOINT, np.concatenate([body, np.roll(nut.rotation.as_quat(), 1)]))
        sim.data.qvel[:] = 0
        self._set_q(Q_HOME)
        for f in self.fingers:
            sim.data.qpos[f] = 0.04 * (1 if f == self.fingers[0] else -1)
        sim.forward()
        self.scene_poses = {"square_peg": Pose(np.array(peg.position, float), peg.rotation.as_quat())}
        self._estimates = {}
        return poses

    def _nut(self) -> Pose:
        """Our nut frame's pose, from robosuite's nut body (at our body_origin keypoint)."""
        q = self.env.sim.data.get_joint_qpos(NUT_JOINT)
        R = Rotation.from_quat(np.roll(q[3:], -1))
        return Pose(np.asarray(q[:3]) - self.offset - R.apply(self.nut_origin), R.as_quat())

    def true_poses(self) -> dict[str, np.ndarray]:
        return {"square_nut": self._nut().as_array(), "square_peg": self.scene_poses["square_peg"].as_array()}

    def observe(self) -> Observation:
        d = self.env.sim.data
        return Observation(ee_pose=self.current_ee_pose(), gripper=np.array([d.qpos[f] for f in self.fingers]),
                           joint_positions=self.current_q(), object_poses=dict(self._estimates),
                           true_object_poses=self.true_poses(), stamp_ns=int(round(d.time * 1e9)), object_joints={})

    def estimate_poses(self) -> dict[str, Pose]:
        self._estimates = {k: Pose(v[:3], v[3:]) for k, v in self.true_poses().items()}
        return dict(self._estimates)

    def current_ee_pose(self) -> Pose:
        return Pose.from_matrix(self._site() @ self.C)

    def current_q(self) -> np.ndarray:
        return np.array([self.env.sim.data.qpos[a] for a in self.arm])

    def plan_and_execute(self, target, mode, attached):
        raise NotImplementedError("MimicGen attempts plan nothing")

    def step(self, target: Pose, gripper: float) -> Observation:
        """mimicgen/env_interfaces/robosuite.py target_pose_to_action: the normalized delta from the grip site."""
        a = pose_to_delta_action(target.matrix() @ np.linalg.inv(self.C), self._site())
        self.env.step(np.concatenate([a, [1.0 if gripper > 0 else -1.0]]))
        return self.observe()

    def task_success(self) -> bool:
        return bool(self.env._check_success())

    def collided(self) -> bool:
        return False

    def close(self) -> None:
        self.env.close()


def pybullet_tip_depth(pb) -> float:
    """How far pybullet_data's finger mesh (collision/finger.obj) reaches beyond panda_grasptarget (m)."""
    import pybullet_data

    w = pb.world
    mesh = Path(pybullet_data.getDataPath()) / "franka_panda" / "meshes" / "collision" / "finger.obj"
    V = np.array([[float(x) for x in ln.split()[1:4]] for ln in mesh.read_text().splitlines() if ln.startswith("v ")])
    ee = w._link_pose(w.ee_link).matrix()
    depth = -np.inf
    for f in w.fingers:  # finger joint j drives link j
        T = w._link_pose(f).matrix()
        depth = max(depth, float(((V @ T[:3, :3].T + T[:3, 3] - ee[:3, 3]) @ ee[:3, 2]).max()))
    return depth


def _final(env) -> dict:
    """Where the attempt left the nut: its offset from the peg in x, y and its height above the table."""
    poses = env.true_poses() if hasattr(env, "true_poses") else {k: v.as_array() for k, v in env.world.object_poses().items()}
    nut, peg = np.asarray(poses["square_nut"][:3]), np.asarray(poses["square_peg"][:3])
    return {"nut_peg_xy_cm": round(float(np.linalg.norm(nut[:2] - peg[:2])) * 100, 2),
            "nut_above_table_cm": round(float(nut[2] - TABLE_Z) * 100, 2)}


def _run(env, demos, task, variant: str, indices, seed: int) -> list[dict]:
    cfg = RunRequest(task="Square", variant=variant, method="mimicgen", seed=seed, profile="paper").config()
    out = []
    for i in indices:
        r = run_attempt(env, demos, task, "mimicgen", i, seed, cfg)
        out.append({"index": i, "success": r.success, "reason": r.reason.value, "source_demo": r.source_demos[0],
                    "steps": 0 if r.episode is None else len(r.episode.actions), **_final(env)})
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--variants", nargs="+", default=["D0", "D1", "D2"])
    p.add_argument("--attempts", type=int, default=40)
    p.add_argument("--first-index", type=int, default=0)
    p.add_argument("--seed", type=int, default=0, help="run seed (bench/datagen's default)")
    p.add_argument("--tip-align", action=argparse.BooleanOptionalAction, default=True,
                   help="put robosuite's fingertips where pybullet's are for the same ee target (module docstring)")
    p.add_argument("--gripper-speeds", type=float, nargs="+", default=[ROBOSUITE_GRIPPER_SPEED, 2.0],
                   help="robosuite PandaGripper.speed per MuJoCo run (0.2 robosuite's; 2.0 closes at once, as ours)")
    p.add_argument("--nut", choices=["robosuite", "ours"], default="robosuite",
                   help="MuJoCo's square nut: robosuite's square-nut.xml, or ours (geometry and mass) with its contact parameters")
    p.add_argument("--site", default=str(ROOT / "out" / "mujoco_site"), help="where robosuite and mujoco are installed")
    p.add_argument("--out", default=str(ROOT / "bench" / "results" / "mujoco_crosscheck.json"))
    a = p.parse_args(argv)
    sys.path.append(a.site)  # after the venv: its numpy, scipy win
    from skillgen_ros.core.dataset.report import wilson_interval
    from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv
    from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos

    task = get_task("Square")
    demos = load_source_demos(expand_bag_paths([str(ROOT / "bags" / "Square")]), task)
    pb = SimGenerationEnv(SimEnvConfig(perception="ground_truth", seed=a.seed))
    pb.reset("Square", "D0", 0)
    pb_tip = pybullet_tip_depth(pb)
    nut_xml = None
    if a.nut == "ours":
        nut_xml = str(our_nut_xml(Path(tempfile.mkdtemp(prefix="skillgen_nut_")) / "square-nut.xml"))
    mj = RobosuiteSquareEnv(pb_tip if a.tip_align else None, nut_xml=nut_xml)
    print(f"fingertips beyond the ee point: pybullet {100 * pb_tip:.2f} cm, robosuite {100 * mj.mj_tip_depth:.2f} cm; "
          f"robosuite's site moved {100 * mj.tip_shift:.2f} cm", flush=True)
    indices = range(a.first_index, a.first_index + a.attempts)
    cells = {}
    for v in a.variants:
        t0 = time.perf_counter()
        runs = {"pybullet": _run(pb, demos, task, v, indices, a.seed)}
        for speed in a.gripper_speeds:
            mj._set_gripper_speed(speed)
            runs[f"mujoco_gripper_speed_{speed:g}"] = _run(mj, demos, task, v, indices, a.seed)
        cell = {"seconds": round(time.perf_counter() - t0, 1)}
        for eng, rows in runs.items():
            k = sum(r["success"] for r in rows)
            lo, hi = wilson_interval(k, len(rows))
            cell[eng] = {"successes": k, "attempts": len(rows), "rate": k / len(rows), "ci95": [lo, hi],
                         "failures": dict(Counter(r["reason"] for r in rows if not r["success"])), "attempts_detail": rows}
            if eng != "pybullet":
                both = [(x["success"], y["success"]) for x, y in zip(runs["pybullet"], rows)]
                cell[eng]["paired_with_pybullet"] = {
                    "both": sum(x and y for x, y in both), "pybullet_only": sum(x and not y for x, y in both),
                    "mujoco_only": sum(y and not x for x, y in both), "neither": sum(not x and not y for x, y in both)}
        cells[f"Square/{v}"] = cell
        print(f"Square/{v}: " + ", ".join(f"{e} {cell[e]['successes']}/{len(indices)}" for e in runs), flush=True)
    import mujoco
    import robosuite
    res = {"command": "PYTHONPATH=$PWD .venv/bin/python bench/datagen/mujoco_crosscheck.py " + " ".join(argv or sys.argv[1:]),
           "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
           "versions": {"robosuite": robosuite.__version__, "mujoco": mujoco.__version__},
           "ee_offset_site_to_grasptarget": mj.C.round(6).tolist(),
           "fingertip_depth_cm": {"pybullet": round(100 * pb_tip, 3), "robosuite": round(100 * mj.mj_tip_depth, 3),
                                  "site_moved": round(100 * mj.tip_shift, 3)}, "base_in_robosuite": mj.offset.round(6).tolist(),
           "nut": a.nut, "nut_mass_kg": round(mj.nut_mass, 5), "tip_align": a.tip_align, "seed": a.seed, "cells": cells}
    Path(a.out).write_text(json.dumps(res, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

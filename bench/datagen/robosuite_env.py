"""A GenerationEnv over robosuite 1.5.2's nut tasks on MuJoCo 3.3.0: Square (NutAssemblySquare) and Nut
Assembly (NutAssembly, both nuts), so MimicGen's attempts run in MuJoCo as they run in pybullet.

Why: bench/datagen/mujoco_crosscheck.py replays *the same attempts* (run seed, index: same scene, source demo,
offsets and action noise; core/generation/mimicgen.py unchanged) in both engines, to tell the engine's share
of a gap to the paper from the rest. This env is robosuite's world as MimicGen's robosuite interface drives
it: its Panda, OSC_POSE controller (robosuite's defaults: kp 150, output_max 0.05 m / 0.5 rad, 20 Hz),
gripper, nuts and pegs, and its own success check (`NutAssembly._check_success`: every nut on its peg and
r_reach < 0.6), read at every step as MimicGen does.

Frames: our world is the Panda base (core/robot.py); robosuite's base body sits at (-0.56, 0, 0.912) with
the same orientation (read from the model, checked). Our EE is panda_grasptarget (pinocchio FK); robosuite
acts on `gripper0_right_grip_site`; the constant transform between them is measured by FK at several joint
configurations and must agree to 1e-6 (checked). The two grippers differ below it: pybullet_data's finger
mesh ends 0.72 cm beyond panda_grasptarget, robosuite's finger mesh 0.07 cm beyond the same point (its pads end
0.41 cm short of it), so a target reached as ours leaves robosuite's fingers 0.65 cm higher on the object
(a demo's nut grasp, 0.9 cm into the 2 cm nut in pybullet, closes on air). Given `pybullet_tip_depth`,
robosuite's grip site is moved that much further along the approach axis, so the fingertips land where ours
do; measured from both models at start. The pegs keep robosuite's body z (their geoms are 20 cm tall,
centred 3 cm below the top of the table; on_peg reads only x, y); each robosuite nut body is placed at our
nut's `body_origin` keypoint (the ring centre; for the square nut 2.75 cm from our nut frame's origin along
the handle axis), handle along +x in both. `our_nut_xml` gives robosuite our nut's boxes and mass instead.

robosuite and MuJoCo are not project dependencies (mujoco_crosscheck.py's docstring installs them).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from skillgen_ros.core.generation.episode import Observation
from skillgen_ros.core.geometry import Pose, make_T
from skillgen_ros.core.robot import Q_HOME
from skillgen_ros.core.skills.actions import pose_to_delta_action
from skillgen_ros.core.tasks import get_task
from skillgen_ros.core.tasks.spec import ObjectSpec

ARM = [f"robot0_joint{i}" for i in range(1, 8)]
FINGERS = ["gripper0_right_finger_joint1", "gripper0_right_finger_joint2"]
ROBOSUITE_GRIPPER_SPEED = 0.2  # models/grippers/panda_gripper.py PandaGripper.speed


@dataclass(frozen=True)
class RobosuiteTask:
    """Our task's robosuite environment and names: our nut id -> robosuite nut name (its free joint is
    `<name>_joint0`), our peg id -> robosuite peg body (pegs_arena.xml), our nut id -> our peg id."""

    env: str
    nuts: dict[str, str]
    pegs: dict[str, str]
    nut_peg: dict[str, str]


# robosuite environments/manipulation/nut_assembly.py: NutAssemblySquare is single_object_mode 2 with the square
# nut; NutAssembly's default single_object_mode 0 asks for both nuts, each on its own peg (peg1 square, peg2 round).
ROBOSUITE_TASKS = {
    "Square": RobosuiteTask("NutAssemblySquare", {"square_nut": "SquareNut"}, {"square_peg": "peg1"},
                            {"square_nut": "square_peg"}),
    "NutAssembly": RobosuiteTask("NutAssembly", {"square_nut": "SquareNut", "round_nut": "RoundNut"},
                                 {"square_peg": "peg1", "round_peg": "peg2"},
                                 {"square_nut": "square_peg", "round_nut": "round_peg"}),
}
_XML_CLASS = {"SquareNut": "SquareNutObject", "RoundNut": "RoundNutObject"}
_XML_FILE = {"SquareNut": "objects/square-nut.xml", "RoundNut": "objects/round-nut.xml"}


def our_nut_xml(nut: ObjectSpec, path: Path) -> Path:
    """robosuite's nut xml with our nut's boxes and mass (core/tasks/objects.py) in place of its own, keeping
    its contact parameters (solimp, solref, friction, condim) and sites: the same object in both engines. The
    body frame is the ring centre, as robosuite's (on_peg reads it)."""
    origin = np.asarray(nut.keypoint("body_origin"), float)
    volume = sum(8 * float(np.prod(pt.size)) for pt in nut.parts)
    geoms = []
    for pt in nut.parts:
        if pt.kind != "box":
            raise ValueError(f"{nut.id} part {pt.kind} is not a box")
        x, y, z = np.asarray(pt.position, float) - origin
        qw = np.roll(np.asarray(pt.quaternion, float), 1)
        geoms.append(f'<geom pos="{x:.6f} {y:.6f} {z:.6f}" quat="{" ".join(f"{v:.6f}" for v in qw)}" '
                     f'size="{" ".join(f"{v:.6f}" for v in pt.size)}" type="box" solimp="0.998 0.998 0.001" '
                     f'solref="0.02 1" density="{nut.mass / volume:.3f}" friction="0.95 0.3 0.1" group="0" condim="4"/>')
    handle = np.asarray(nut.keypoint("handle"), float) - origin
    path.write_text(f"""<mujoco model="{nut.type.replace('_', '-')}">
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


def _use_nut_xmls(paths: dict[str, str]) -> None:
    """Make robosuite's nut objects load `paths[name]` (robosuite nut name -> xml; absent: its own xml)."""
    from robosuite.models.objects import xml_objects
    from robosuite.utils.mjcf_utils import xml_path_completion

    for name, cls in _XML_CLASS.items():
        path = paths.get(name) or xml_path_completion(_XML_FILE[name])

        def init(self, name, _path=path):
            xml_objects.MujocoXMLObject.__init__(self, _path, name=name, joints=[dict(type="free", damping="0.0005")],
                                                 obj_type="all", duplicate_collision_geoms=True)
        setattr(getattr(xml_objects, cls), "__init__", init)


class RobosuiteNutEnv:
    """GenerationEnv (core/generation/attempt.py) over robosuite's Square or Nut Assembly; MimicGen needs no
    planner."""

    def __init__(self, task: str = "Square", pybullet_tip_depth: float | None = None,
                 gripper_speed: float = ROBOSUITE_GRIPPER_SPEED, nut_xmls: dict[str, str] | None = None):
        """pybullet_tip_depth: how far our finger mesh reaches beyond panda_grasptarget (m); given, robosuite's
        fingertips are moved to the same depth (see the module docstring); None leaves the grip site as is.
        nut_xmls: our nut id -> an xml to load in place of robosuite's (our_nut_xml)."""
        import robosuite
        from robosuite.controllers import load_composite_controller_config
        from skillgen_ros.core.planning.kinematics import PandaKinematics

        if task not in ROBOSUITE_TASKS:
            raise ValueError(f"no robosuite task for {task!r}; known: {sorted(ROBOSUITE_TASKS)}")
        self.task, self.spec = task, ROBOSUITE_TASKS[task]
        _use_nut_xmls({self.spec.nuts[k]: v for k, v in (nut_xmls or {}).items()})
        self.env = robosuite.make(self.spec.env, robots="Panda",
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
        self.pegs = {k: m.body_name2id(v) for k, v in self.spec.pegs.items()}
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
        self.peg_z = {k: float(m.body_pos[b][2]) for k, b in self.pegs.items()}
        self.nut_mass = {k: float(m._model.body_subtreemass[m.body_name2id(f"{v}_main")]) for k, v in self.spec.nuts.items()}
        spec = get_task(task)
        self.nut_origin = {k: np.asarray(spec.object(k).keypoint("body_origin"), float) for k in self.spec.nuts}
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
        T = make_T(d.site_xpos[self.site], d.site_xmat[self.site].reshape(3, 3))
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
        if task != self.task:
            raise ValueError(f"this env runs robosuite's {self.spec.env} ({self.task}), not {task}")
        poses = get_task(task).sample_reset(variant, np.random.default_rng(seed))  # as sim/world.py samples
        self.env.reset()
        sim = self.env.sim
        self.scene_poses = {}
        for k, body in self.pegs.items():
            peg = poses[k]
            sim.model.body_pos[body] = [*(peg.position[:2] + self.offset[:2]), self.peg_z[k]]
            sim.model.body_quat[body] = np.roll(peg.rotation.as_quat(), 1)
            self.scene_poses[k] = Pose(np.array(peg.position, float), peg.rotation.as_quat())
        for k, name in self.spec.nuts.items():  # our nut frame; robosuite's body sits at our body_origin keypoint
            nut = poses[k]
            body = nut.rotation.apply(self.nut_origin[k]) + nut.position + self.offset
            sim.data.set_joint_qpos(f"{name}_joint0", np.concatenate([body, np.roll(nut.rotation.as_quat(), 1)]))
        sim.data.qvel[:] = 0
        self._set_q(Q_HOME)
        for f in self.fingers:
            sim.data.qpos[f] = 0.04 * (1 if f == self.fingers[0] else -1)
        sim.forward()
        self._estimates = {}
        return poses

    def _nut(self, k: str) -> Pose:
        """Our nut frame's pose, from robosuite's nut body (at our body_origin keypoint)."""
        q = self.env.sim.data.get_joint_qpos(f"{self.spec.nuts[k]}_joint0")
        R = Rotation.from_quat(np.roll(q[3:], -1))
        return Pose(np.asarray(q[:3]) - self.offset - R.apply(self.nut_origin[k]), R.as_quat())

    def true_poses(self) -> dict[str, np.ndarray]:
        return {**{k: self._nut(k).as_array() for k in self.spec.nuts},
                **{k: p.as_array() for k, p in self.scene_poses.items()}}

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

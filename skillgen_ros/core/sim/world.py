"""SimWorld: one pybullet world with the Panda, the table and a task's objects.

Each world owns a fresh DIRECT client and rebuilds everything on reset (resetSimulation), so a
(task, variant, seed) plus the same command sequence replays bit-identically. The arm's default
velocity motors are disabled; every physics step applies torques from the OSC or joint controller.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Iterable, Mapping

import numpy as np
import pybullet
from pybullet_utils.bullet_client import BulletClient

from ..errors import InvalidInputError
from ..geometry import Pose
from ..robot import (ARM_JOINTS, CONTROL_HZ, EE_LINK, FINGER_JOINTS, GRIPPER_MAX_WIDTH, HAND_LINK, Q_HOME,
                     TABLE_CENTER_XY, TABLE_FULL_SIZE, TABLE_Z,
                     panda_urdf_path)
from ..tasks import SceneDescription, SceneState, get_task, validate_seed
from ..tasks.objects import center_of_mass
from ..tasks.spec import DEFAULT_CAMERA_SIZE, ObjectSpec
from . import articulation
from . import camera as cam
from .assets import lowpoly_panda_urdf
from .commands import (Contact, JointTrajectory, TrajectoryCode, TrajectoryResult,  # noqa: F401
                       validate_osc_target, validate_trajectory)
from .contact_model import with_finger_pads
from .contacts import hand_wrench
from .control import (DEFAULT_GOAL_TOLERANCE, ActiveTrajectory, JointGains, OscGains, TrajectorySampler,
                      joint_torques, osc_torques)
from .hand import STATE_SIZE as HAND_STATE_SIZE
from .hand import FrankaHand

TABLE_HALF = tuple(x / 2 for x in TABLE_FULL_SIZE)   # robosuite's 0.8 x 0.8 x 0.05 table (core/robot.py)
TABLE_CENTER = (*TABLE_CENTER_XY, TABLE_Z - TABLE_HALF[2])
# Bullet multiplies two bodies' frictions (MuJoCo takes the larger): 1.5 x the objects' 1.0. robosuite's finger
# pads (panda_gripper.xml) have friction "2 0.05 0.0001"; with 2.0 / 0.05 here Threading D0 made the same 5/40
# (docs/tasks.md).
FINGER_LATERAL_FRICTION = 1.5
FINGER_SPINNING_FRICTION = 0.01


@dataclass
class SimConfig:
    control_hz: float = CONTROL_HZ
    physics_hz: float = 240.0
    osc: OscGains = field(default_factory=OscGains)
    joint: JointGains = field(default_factory=JointGains)
    gripper_force: float = 20.0       # N per finger
    gripper_hold_force: float = 2.0   # N per finger once an opening move reaches its width (Franka move())
    cameras: tuple[cam.CameraConfig, ...] = ()
    solver_iterations: int = 50       # contact_model.py names the sets of these two that results used
    finger_pads: bool = False         # robosuite's finger pads, rigid finger contact (contact_model.py)
    lowpoly_visuals: bool = True      # render the Panda with its collision meshes (~20x faster TinyRenderer)


class SimWorld:
    """The simulated robot + scene. All poses are in the world frame (robot base at the origin)."""

    def __init__(self, config: SimConfig | None = None, gui: bool = False, **overrides):
        """`overrides` set SimConfig fields (control_hz, physics_hz, cameras, osc, ...); cameras may be
        CameraConfig objects or the names "front" / "wrist" (default resolution, no noise)."""
        cfg = config or SimConfig()
        noise = overrides.pop("depth_noise", None)  # (base m, quadratic 1/m[, dropout]) for every camera
        if overrides:
            cfg = SimConfig(**{**cfg.__dict__, **overrides})
        cfg.cameras = tuple(c if isinstance(c, cam.CameraConfig) else cam.CameraConfig(str(c)) for c in cfg.cameras)
        if noise is not None:
            base, quad, drop = ([float(x) for x in np.atleast_1d(noise)] + [0.0, 0.0, 0.0])[:3]
            cfg.cameras = tuple(replace(c, noise_base=base, noise_quadratic=quad, dropout=drop) for c in cfg.cameras)
        self.cfg = cfg
        if self.cfg.physics_hz % self.cfg.control_hz:
            raise InvalidInputError("physics_hz must be an integer multiple of control_hz")
        self.hand = FrankaHand(self.cfg.gripper_force, self.cfg.gripper_hold_force)  # validates the forces
        self.substeps = int(round(self.cfg.physics_hz / self.cfg.control_hz))
        self.dt = 1.0 / self.cfg.physics_hz
        self.p = BulletClient(connection_mode=pybullet.GUI if gui else pybullet.DIRECT)
        if any((c.width == 0) != (c.height == 0) or min(c.width, c.height) < 0 for c in self.cfg.cameras):
            raise InvalidInputError("a camera's width and height are both > 0, or both 0 (the task's size)",
                                    "INVALID_PARAMETER")
        self.cameras = self._sized_cameras(DEFAULT_CAMERA_SIZE)
        self._urdf = lowpoly_panda_urdf() if self.cfg.lowpoly_visuals else panda_urdf_path()
        if self.cfg.finger_pads:
            self._urdf = with_finger_pads(self._urdf)
        self.scene: SceneDescription | None = None
        self.time = 0.0
        self._build_scene({}, ())

    @property
    def control_hz(self) -> float:
        return self.cfg.control_hz

    # ------------------------------------------------------------------ scene
    def _build_scene(self, poses: dict[str, Pose], objects: tuple[ObjectSpec, ...]) -> None:
        p = self.p
        p.resetSimulation()
        p.setPhysicsEngineParameter(fixedTimeStep=self.dt, numSolverIterations=self.cfg.solver_iterations,
                                    deterministicOverlappingPairs=1, numSubSteps=0)
        p.setGravity(0, 0, -9.81)
        table_col = p.createCollisionShape(p.GEOM_BOX, halfExtents=TABLE_HALF)
        table_vis = p.createVisualShape(p.GEOM_BOX, halfExtents=TABLE_HALF, rgbaColor=(0.82, 0.72, 0.58, 1))
        self.table = p.createMultiBody(0, table_col, table_vis, TABLE_CENTER)
        p.changeDynamics(self.table, -1, lateralFriction=1.0)
        urdf = self._urdf
        self.robot = p.loadURDF(urdf, (0, 0, 0), useFixedBase=True,
                                flags=p.URDF_USE_INERTIA_FROM_FILE | p.URDF_ENABLE_CACHED_GRAPHICS_SHAPES)
        names = {p.getJointInfo(self.robot, i)[1].decode(): i for i in range(p.getNumJoints(self.robot))}
        links = {p.getJointInfo(self.robot, i)[12].decode(): i for i in range(p.getNumJoints(self.robot))}
        self.link_names = {v: k for k, v in links.items()}
        self.arm = [names[j] for j in ARM_JOINTS]
        self.fingers = [names[j] for j in FINGER_JOINTS]
        self.movable = self.arm + self.fingers
        self.ee_link, self.hand_link = links[EE_LINK], links[HAND_LINK]
        for i in range(-1, p.getNumJoints(self.robot)):
            p.changeDynamics(self.robot, i, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0)
        for f in self.fingers:
            p.changeDynamics(self.robot, f, lateralFriction=FINGER_LATERAL_FRICTION,
                             spinningFriction=FINGER_SPINNING_FRICTION, frictionAnchor=1)
        for j, q in zip(self.arm, Q_HOME):
            p.resetJointState(self.robot, j, q)
        for f in self.fingers:
            p.resetJointState(self.robot, f, GRIPPER_MAX_WIDTH / 2)
        p.setJointMotorControlArray(self.robot, self.arm, p.VELOCITY_CONTROL, forces=[0.0] * 7)
        # couple the fingers (the real Panda's mechanism): without it a grasped object floats
        # between two force-saturated finger motors
        gear = p.createConstraint(self.robot, self.fingers[0], self.robot, self.fingers[1], p.JOINT_GEAR,
                                  [1, 0, 0], [0, 0, 0], [0, 0, 0])
        p.changeConstraint(gear, gearRatio=-1, erp=0.1, maxForce=100)
        self.bodies: dict[str, int] = {}
        self._com: dict[str, np.ndarray] = {}
        self._articulated = {o.id: o for o in objects if o.joints}
        for o in objects:
            self._com[o.id] = center_of_mass(o.parts) if o.mass > 0 and not o.joints else np.zeros(3)
            self.bodies[o.id] = self._spawn(o, poses[o.id])
        self.body_names = {v: k for k, v in self.bodies.items()} | {self.table: "table"}
        self.hand = FrankaHand(self.cfg.gripper_force, self.cfg.gripper_hold_force)
        self.hand.apply(p, self.robot, self.fingers)
        self._hold_q = np.array(Q_HOME)
        self._osc_target = self.ee_pose()
        self._mode = "joint_hold"
        self._traj: ActiveTrajectory | None = None
        self.time = 0.0

    def _spawn(self, o: ObjectSpec, pose: Pose) -> int:
        p = self.p
        if o.joints or len(o.parts) > articulation.MAX_COMPOUND:  # a fixture with links (core/sim/articulation.py)
            return articulation.spawn(p, o, pose)
        col, vis = articulation.shape_arrays(p, o.parts, o.color)
        # createMultiBody takes the object (link) frame; get/resetBasePositionAndOrientation use the
        # inertial frame (offset by the centre of mass): _object_pose/_set_object_pose convert.
        body = p.createMultiBody(o.mass, col, vis, pose.position.tolist(), pose.quaternion.tolist(),
                                 baseInertialFramePosition=self._com[o.id].tolist())
        p.changeDynamics(body, -1, lateralFriction=o.friction, spinningFriction=0.002, rollingFriction=0.0001,
                         frictionAnchor=1)
        return body

    def reset(self, task: str, variant: str, seed: int) -> SceneDescription:
        """Sample the task's reset distribution with `seed`, rebuild the world, return the scene."""
        spec = get_task(task)
        seed = validate_seed(seed)
        objects = spec.objects_for(variant)
        poses = spec.sample_reset(variant, np.random.default_rng(seed))
        self._build_scene(poses, objects)
        self.task = spec
        self.cameras = self._sized_cameras(spec.camera_size)
        self._noise_rng = np.random.default_rng([seed, 1])
        self.scene = SceneDescription(task, variant, seed, objects, self.object_poses(), self.joint_positions(),
                                      self.object_joints())
        return self.scene

    # ------------------------------------------------------------------ state
    def _joint_state(self) -> tuple[np.ndarray, np.ndarray]:
        s = self.p.getJointStates(self.robot, self.movable)
        return np.array([x[0] for x in s]), np.array([x[1] for x in s])

    def joint_positions(self) -> np.ndarray:
        """(7,) arm joint positions in ARM_JOINTS order."""
        return self._joint_state()[0][:7]

    def joint_velocities(self) -> np.ndarray:
        return self._joint_state()[1][:7]

    def finger_positions(self) -> np.ndarray:
        return self._joint_state()[0][7:]

    def gripper_width(self) -> float:
        return float(np.sum(self.finger_positions()))

    @property
    def gripper_command(self) -> float:
        """The last gripper command, -1 open .. +1 closed."""
        return self.hand.command

    def is_grasping(self) -> bool:
        """Fingers commanded closed but stalled on something before fully closing."""
        return self.hand.is_grasping(self.gripper_width())

    def _link_pose(self, link: int) -> Pose:
        s = self.p.getLinkState(self.robot, link, computeForwardKinematics=True)
        return Pose(s[4], s[5])

    def ee_pose(self) -> Pose:
        """Pose of panda_grasptarget in the world frame."""
        return self._link_pose(self.ee_link)

    def hand_pose(self) -> Pose:
        return self._link_pose(self.hand_link)

    def _object_pose(self, oid: str) -> Pose:
        pos, quat = self.p.getBasePositionAndOrientation(self.bodies[oid])
        R = Pose(pos, quat).rotation
        return Pose(np.asarray(pos) - R.apply(self._com[oid]), quat)

    def _set_object_pose(self, oid: str, pose: Pose) -> None:
        pos = pose.position + pose.rotation.apply(self._com[oid])
        self.p.resetBasePositionAndOrientation(self.bodies[oid], pos.tolist(), pose.quaternion.tolist())

    def object_poses(self) -> dict[str, Pose]:
        """True object-frame poses (origin at the bounding-box centre) of the scene objects."""
        return {oid: self._object_pose(oid) for oid in self.bodies}

    def object_joints(self) -> dict[str, float]:
        """Articulated objects' joint values {"<object>/<joint>": rad or m} (core/tasks/articulation.py)."""
        return articulation.values(self.p, self.bodies, self._articulated)

    def scene_state(self) -> SceneState:
        """What the task's success rule reads: true object poses and joint values, the EE position, the gripper."""
        return SceneState(self.object_poses(), self.ee_pose().position.copy(), float(self.hand.command),
                          self.object_joints())

    def task_success(self) -> bool:
        return self.scene is not None and self.task.is_success(self.scene_state())

    def get_state(self) -> np.ndarray:
        """Flat state: [time, q(9), qd(9), per object (scene order): pos 3, quat 4, lin vel 3, ang vel 3,
        per articulated object's joint: value, velocity, gripper mode: command, finger target, finger
        force, commanded force, opening].

        Object pose = object frame; velocities are those of the centre of mass (pybullet's base). The
        gripper mode is what the finger motors are doing (a grasp holds 20 N, an arrived opening
        move 2 N), so a restored state continues as the original would have."""
        q, qd = self._joint_state()
        parts = [np.array([self.time]), q, qd]
        for oid, b in self.bodies.items():
            lin, ang = self.p.getBaseVelocity(b)
            parts.append(np.concatenate([self._object_pose(oid).as_array(), lin, ang]))
        parts.append(articulation.state(self.p, self.bodies, self._articulated))
        parts.append(self.hand.state())
        return np.concatenate(parts)

    def set_state(self, state) -> None:
        """Restore a get_state() vector (same scene); the controller then holds the restored pose."""
        s = np.asarray(state, float)
        n = 1 + 18 + 13 * len(self.bodies) + articulation.state_size(self._articulated) + HAND_STATE_SIZE
        if s.shape != (n,) or not np.all(np.isfinite(s)):
            raise InvalidInputError(f"state must be {n} finite values for this scene, got shape {s.shape}")
        self.hand.set_state(s[-HAND_STATE_SIZE:])  # validates before anything moves
        self.time = float(s[0])
        for k, j in enumerate(self.movable):
            self.p.resetJointState(self.robot, j, s[1 + k], s[10 + k])
        for k, (oid, b) in enumerate(self.bodies.items()):
            o = s[19 + 13 * k: 32 + 13 * k]
            self._set_object_pose(oid, Pose(o[:3], o[3:7] / np.linalg.norm(o[3:7])))
            self.p.resetBaseVelocity(b, o[7:10].tolist(), o[10:13].tolist())
        articulation.set_state(self.p, self.bodies, self._articulated, s[19 + 13 * len(self.bodies):])
        self.hand.apply(self.p, self.robot, self.fingers)
        self._hold_q = s[1:8].copy()
        self._osc_target = self.ee_pose()
        self._mode, self._traj = "joint_hold", None

    def show_state(self, q, object_poses: Mapping[str, Pose], joints: Mapping[str, float] | None = None) -> None:
        """Place the arm and fingers (q: 7 or 9 positions), the objects and articulated objects' joints
        ({"<object>/<joint>": value}, others kept) kinematically, no physics: a recorded step re-shown
        for rendering (core/dataset/render.py), or a scene set up by hand."""
        q = np.asarray(q, float).reshape(-1)
        for j, v in zip(self.movable, q):
            self.p.resetJointState(self.robot, j, float(v), 0.0)
        for oid, pose in object_poses.items():
            if oid in self.bodies:
                self._set_object_pose(oid, pose)
        articulation.show(self.p, self.bodies, self._articulated, joints or {})

    # ------------------------------------------------------------------ control
    def _dynamics(self, q9, qd9):
        p = self.p
        M = np.array(p.calculateMassMatrix(self.robot, q9.tolist()))[:7, :7]
        h = np.array(p.calculateInverseDynamics(self.robot, q9.tolist(), qd9.tolist(), [0.0] * 9))[:7]
        return M, h

    def _physics_step(self) -> None:
        q9, qd9 = self._joint_state()
        q, qd = q9[:7], qd9[:7]
        M, h = self._dynamics(q9, qd9)
        if self._mode == "osc":
            lin, ang = self.p.calculateJacobian(self.robot, self.ee_link, [0.0, 0.0, 0.0], q9.tolist(),
                                                qd9.tolist(), [0.0] * 9)
            J = np.vstack([np.array(lin)[:, :7], np.array(ang)[:, :7]])
            st = self.p.getLinkState(self.robot, self.ee_link, computeForwardKinematics=True)
            ee_R = np.array(self.p.getMatrixFromQuaternion(st[5])).reshape(3, 3)
            tau = osc_torques(self._osc_target.position, self._target_R, np.array(st[4]), ee_R, J, M, h, q, qd,
                              Q_HOME, self.cfg.osc)
        elif self._mode == "trajectory":
            qd_, vd, ad = self._traj.sampler(self._traj.t)
            tau = joint_torques(qd_, vd, ad, q, qd, M, h, self.cfg.joint)
            self._traj.t += self.dt
        else:
            tau = joint_torques(self._hold_q, np.zeros(7), np.zeros(7), q, qd, M, h, self.cfg.joint)
        if self.hand.arrived(q9[7] + q9[8]):
            self.hand.apply(self.p, self.robot, self.fingers)
        self.p.setJointMotorControlArray(self.robot, self.arm, self.p.TORQUE_CONTROL, forces=tau.tolist())
        self.p.stepSimulation()
        self.time += self.dt

    def gripper(self, command: float) -> None:
        """-1 open .. +1 closed (robosuite convention), force-limited by gripper_force (hand.py: a
        grasp keeps its force, an opening move drops to gripper_hold_force once it arrives)."""
        if self.hand.close_open(command, self.gripper_width()):
            self.hand.apply(self.p, self.robot, self.fingers)

    def gripper_to(self, width: float, max_effort: float) -> None:
        """Move the fingers to opening `width` (m) with at most `max_effort` N per finger."""
        if self.hand.move_to(width, max_effort, self.gripper_width()):
            self.hand.apply(self.p, self.robot, self.fingers)

    def step(self, osc_target: Pose, gripper: float | None = None) -> None:
        """One control period tracking an absolute EE target with the OSC (validated; may raise)."""
        target = validate_osc_target(osc_target.position, osc_target.quaternion)
        if gripper is not None:
            self.gripper(gripper)
        self._osc_target, self._mode, self._traj = target, "osc", None
        self._target_R = target.rotation.as_matrix()
        for _ in range(self.substeps):
            self._physics_step()
        self._hold_q = self.joint_positions()

    def idle(self, periods: int = 1) -> None:
        """Advance time holding the current command (OSC target, trajectory or joint hold)."""
        for _ in range(periods * self.substeps):
            self._physics_step()

    def start_trajectory(self, joint_names: Iterable[str], times, positions, velocities=None,
                         goal_tolerance: float = 0.0) -> JointTrajectory:
        """Validate (raises TrajectoryError) and begin tracking; advance with step_trajectory()."""
        traj = validate_trajectory(joint_names, times, positions, velocities, self.joint_positions())
        tol = goal_tolerance if goal_tolerance > 0 else DEFAULT_GOAL_TOLERANCE
        self._traj, self._mode = ActiveTrajectory(TrajectorySampler(traj), goal_tolerance=tol), "trajectory"
        return traj

    def step_trajectory(self) -> tuple[float, np.ndarray, TrajectoryResult | None]:
        """One control period of the active trajectory: (progress 0..1, desired q, result when done)."""
        tr = self._traj
        if tr is None or self._mode != "trajectory":
            raise InvalidInputError("no active trajectory", "NO_TRAJECTORY")
        for _ in range(self.substeps):
            self._physics_step()
        q_des = tr.sampler(tr.t)[0]
        if tr.check_goal(self.joint_positions()) is not None:
            self._hold_q = tr.sampler.traj.positions[-1].copy()
            self._mode, self._traj = "joint_hold", None
            self._osc_target = self.ee_pose()
        return tr.progress, q_des, tr.done

    def execute_joint_trajectory(self, times, positions, velocities=None, joint_names=ARM_JOINTS,
                                 goal_tolerance: float = 0.0) -> TrajectoryResult:
        """Run a whole trajectory to completion (validation errors are raised, not returned)."""
        self.start_trajectory(joint_names, times, positions, velocities, goal_tolerance)
        while True:
            _, _, done = self.step_trajectory()
            if done is not None:
                return done

    # ------------------------------------------------------------------ contacts
    def robot_contacts(self, object_ids: Iterable[str] | None = None, distance: float = 0.0) -> list[Contact]:
        """Robot contacts (or gaps below `distance`) with the named scene bodies (default: all + table)."""
        ids = list(self.body_names.values()) if object_ids is None else list(object_ids)
        out = []
        for name in ids:
            b = self.table if name == "table" else self.bodies.get(name)
            if b is None:
                continue
            pts = (self.p.getClosestPoints(self.robot, b, distance) if distance > 0
                   else self.p.getContactPoints(self.robot, b))
            out += [Contact(name, self.link_names.get(c[3], "panda_link0"), float(c[8]), float(c[9])) for c in pts]
        return out

    def robot_in_collision_with(self, object_ids: Iterable[str]) -> bool:
        return any(c.distance <= 0.0 for c in self.robot_contacts(object_ids))

    def ee_wrench(self) -> np.ndarray:
        """(6,) external force/torque on the hand and fingers, world frame, torque about the EE."""
        return hand_wrench(self.p, self.robot, [self.hand_link, *self.fingers], self.ee_pose().position)

    # ------------------------------------------------------------------ cameras
    def _sized_cameras(self, size: tuple[int, int]) -> dict[str, cam.CameraConfig]:
        """The configured cameras, each 0 x 0 one at `size` (the scene's task's camera_size)."""
        return {c.name: c.sized(size) for c in self.cfg.cameras}

    def camera_pose(self, name: str) -> np.ndarray:
        if name == "front":
            return cam.front_camera_pose()
        if name == "wrist":
            return self.hand_pose().matrix() @ cam.wrist_in_hand()
        raise InvalidInputError(f"unknown camera {name!r}", "UNKNOWN_CAMERA")

    def render(self, name: str) -> cam.CameraFrame:
        cfg = self.cameras.get(name)
        if cfg is None:
            raise InvalidInputError(f"camera {name!r} not configured; have {list(self.cameras)}", "UNKNOWN_CAMERA")
        rng = getattr(self, "_noise_rng", None) or np.random.default_rng(0)
        return cam.render(self.p, cfg, self.camera_pose(name), rng)

    def close(self) -> None:
        try:
            self.p.disconnect()
        except pybullet.error:
            pass

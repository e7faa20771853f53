"""MockWorld: a kinematic stand-in for SimWorld with the same driver-facing API, no physics.

An OSC target is reached in one period: the joints jump to the local IK solution from where they
are (Newton from the current q, the planner's solver), so joint_states and the EE pose always
agree, as they do on the robot -- a node that takes the hand's pose from FK of joint_states (the
skill_replay node) sees the hand move. A target the arm cannot reach from there leaves it where
it is, as a real OSC stalls. Trajectories complete instantly (the joints jump to the last point,
the EE follows by FK), objects stay where reset put them, and "cameras" return mesh-surface
points of the objects plus a table patch, without occlusion. It imports no pybullet, and the
kinematics (pinocchio, numba) load on the first motion, so the node starts in under a second.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InvalidInputError
from ..geometry import Pose
from ..robot import GRIPPER_MAX_WIDTH, Q_HOME, TABLE_Z
from ..tasks import SceneDescription, SceneState, get_task, validate_seed
from ..tasks.articulation import initial_joint_values
from ..tasks.shapes import read_obj
from ..tasks.spec import DEFAULT_CAMERA_SIZE
from . import camera as cam
from .commands import TrajectoryCode, TrajectoryResult, validate_gripper, validate_osc_target, validate_trajectory

# panda_grasptarget at Q_HOME (pybullet_data panda), pointing down with x along world x.
HOME_EE_POSE = Pose(np.array([0.46348, 0.0, 0.40119]), np.array([1.0, 0.0, 0.0, 0.0]))
HAND_TO_EE = 0.105
POINTS_PER_OBJECT = 400


def surface_samples(mesh_path: str, n: int, rng: np.random.Generator) -> np.ndarray:
    """Area-weighted random points on an OBJ's triangles (object frame)."""
    v, f = read_obj(Path(mesh_path))
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    idx = rng.choice(len(f), size=n, p=area / area.sum())
    a, b = rng.random((2, n, 1))
    flip = (a + b) > 1
    a, b = np.where(flip, 1 - a, a), np.where(flip, 1 - b, b)
    t = tri[idx]
    return t[:, 0] + a * (t[:, 1] - t[:, 0]) + b * (t[:, 2] - t[:, 0])


class MockWorld:
    """Same method names as SimWorld for what the driver node uses."""

    def __init__(self, control_hz: float = 20.0, cameras: tuple = ()):
        self.control_hz = control_hz
        cfgs = (c if isinstance(c, cam.CameraConfig) else cam.CameraConfig(str(c)) for c in cameras)
        # a 0 x 0 camera (the task's size on the sim) is the default size here: the mock's clouds are mesh samples
        self.cameras = {c.name: c.sized(DEFAULT_CAMERA_SIZE) for c in cfgs}
        self.scene: SceneDescription | None = None
        self.time = 0.0
        self._q = np.array(Q_HOME)
        self._ee = HOME_EE_POSE
        self._width = GRIPPER_MAX_WIDTH
        self.gripper_command = -1.0
        self._poses: dict[str, Pose] = {}
        self._points = np.zeros((0, 3))
        self._kin = self._ik = None  # loaded on the first motion

    def _kinematics(self):
        if self._ik is None:
            from ..planning.ik import IKSolver
            from ..planning.kinematics import PandaKinematics

            self._kin = PandaKinematics()
            self._ik = IKSolver(self._kin, rng=0)
        return self._kin, self._ik

    def reset(self, task: str, variant: str, seed: int) -> SceneDescription:
        spec = get_task(task)
        seed = validate_seed(seed)
        objects = spec.objects_for(variant)
        self._poses = spec.sample_reset(variant, np.random.default_rng(seed))
        self.task, self.time = spec, 0.0
        self._q, self._ee, self._width, self.gripper_command = np.array(Q_HOME), HOME_EE_POSE, GRIPPER_MAX_WIDTH, -1.0
        rng = np.random.default_rng([seed, 2])
        pts = [self._poses[o.id].rotation.apply(surface_samples(o.mesh_path, POINTS_PER_OBJECT, rng))
               + self._poses[o.id].position for o in objects]
        gx, gy = np.meshgrid(np.linspace(0.2, 0.92, 37), np.linspace(-0.4, 0.4, 41))  # robosuite's table
        pts.append(np.c_[gx.ravel(), gy.ravel(), np.full(gx.size, TABLE_Z)])
        self._points = np.vstack(pts)
        self._joints = initial_joint_values(objects)   # kinematic: nothing moves a lid or drawer
        self.scene = SceneDescription(task, variant, seed, objects, dict(self._poses), self._q.copy(), dict(self._joints))
        return self.scene

    # state ------------------------------------------------------------
    def joint_positions(self) -> np.ndarray:
        return self._q.copy()

    def joint_velocities(self) -> np.ndarray:
        return np.zeros(7)

    def finger_positions(self) -> np.ndarray:
        return np.full(2, self._width / 2)

    def gripper_width(self) -> float:
        return self._width

    def is_grasping(self) -> bool:
        return False

    def ee_pose(self) -> Pose:
        return self._ee

    def ee_wrench(self) -> np.ndarray:
        return np.zeros(6)  # kinematic: nothing pushes back

    def object_poses(self) -> dict[str, Pose]:
        return dict(self._poses)

    def object_joints(self) -> dict[str, float]:
        return dict(getattr(self, "_joints", {}))

    def task_success(self) -> bool:
        return self.scene is not None and self.task.is_success(
            SceneState(dict(self._poses), self._ee.position.copy(), float(self.gripper_command), self.object_joints()))

    # control ----------------------------------------------------------
    def gripper(self, command: float) -> None:
        g = validate_gripper(command)
        self.gripper_command, self._width = g, (1.0 - g) / 2.0 * GRIPPER_MAX_WIDTH

    def gripper_to(self, width: float, max_effort: float) -> None:
        if not (np.isfinite(width) and np.isfinite(max_effort)) or max_effort <= 0:
            raise InvalidInputError(f"gripper width {width} / effort {max_effort} invalid")
        self._width = float(np.clip(width, 0.0, GRIPPER_MAX_WIDTH))
        self.gripper_command = 1.0 - 2.0 * self._width / GRIPPER_MAX_WIDTH

    def step(self, osc_target: Pose, gripper: float | None = None) -> None:
        target = validate_osc_target(osc_target.position, osc_target.quaternion)
        if gripper is not None:
            self.gripper(gripper)
        kin, ik = self._kinematics()
        q = ik.solve_local(target.matrix(), self._q, iters=100)
        if q is not None:  # unreachable from here: the arm stays put
            self._q, self._ee = q, Pose.from_matrix(kin.fk(q))
        self.time += 1.0 / self.control_hz

    def idle(self, periods: int = 1) -> None:
        self.time += periods / self.control_hz

    def start_trajectory(self, joint_names, times, positions, velocities=None, goal_tolerance: float = 0.0):
        traj = validate_trajectory(joint_names, times, positions, velocities, self._q)
        self._pending = traj
        return traj

    def step_trajectory(self):
        traj, self._pending = getattr(self, "_pending", None), None
        if traj is None:
            raise InvalidInputError("no active trajectory", "NO_TRAJECTORY")
        self._q = traj.positions[-1].copy()
        self._ee = Pose.from_matrix(self._kinematics()[0].fk(self._q))
        return 1.0, self._q.copy(), TrajectoryResult(TrajectoryCode.SUCCESSFUL, "goal reached (kinematic)", 0.0)

    # cameras ----------------------------------------------------------
    def camera_pose(self, name: str) -> np.ndarray:
        if name == "front":
            return cam.front_camera_pose()
        hand = self._ee.matrix() @ np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, -HAND_TO_EE], [0, 0, 0, 1.0]])
        return hand @ cam.wrist_in_hand()

    def render(self, name: str) -> cam.CameraFrame:
        cfg = self.cameras.get(name)
        if cfg is None:
            raise InvalidInputError(f"camera {name!r} not configured; have {list(self.cameras)}", "UNKNOWN_CAMERA")
        h, w = cfg.height, cfg.width
        return cam.CameraFrame(name, np.zeros((h, w, 3), np.uint8), np.full((h, w), np.nan, np.float32),
                               cfg.intrinsics(), self.camera_pose(name), self._points.copy(),
                               np.full((h, w), -1, np.int64))

    def close(self) -> None:
        pass

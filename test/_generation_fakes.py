"""Test doubles for the generation core: a kinematic pick-and-place world and a scripted source demo.

The fake world moves the end effector exactly to each commanded pose, attaches the cube when the
gripper closes near it and drops it when it opens; success = cube resting on the plate. It is
enough to exercise Algorithm 1's bookkeeping (frames, actions, labels, failures) without a sim.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from skillgen_ros.core.generation.episode import Observation
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.skills.annotation import Annotation
from skillgen_ros.core.skills.auto_annotation import AnnotationRules, SkillRule, auto_annotate
from skillgen_ros.core.skills.source_demos import DemoArrays, source_demo_from_arrays

CUBE_HALF = 0.02
PLATE_TOP = 0.01
DOWN = Rotation.from_euler("x", np.pi)


@dataclass(frozen=True)
class FakeSkill:
    index: int
    object_id: str
    name: str
    mode: str
    attached_object: str | None = None


@dataclass(frozen=True)
class FakeObject:
    id: str


@dataclass(frozen=True)
class FakeTask:
    name: str = "pick_place"
    objects: tuple = (FakeObject("cube"), FakeObject("plate"))
    skills: tuple = (FakeSkill(0, "cube", "pick", "transit"), FakeSkill(1, "plate", "place", "transfer", "cube"))


RULES = AnnotationRules(per_skill={
    0: SkillRule(start_distance=0.06, post_steps=5),
    1: SkillRule(start_distance=0.07, post_steps=3, offset=(0.0, 0.0, PLATE_TOP + CUBE_HALF)),
})


def _T(pos, rot: Rotation) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rot.as_matrix()
    T[:3, 3] = pos
    return T


class FakeWorld:
    """Implements the GenerationEnv protocol kinematically."""

    def __init__(self, plan_status="OK", collide=False, perception_fails=False, ee_offset_noise=0.0,
                 images=False):
        self.plan_status = plan_status
        self.collide = collide
        self.perception_fails = perception_fails
        self.images = images
        self.no_truth = False  # True: a robot without ground truth (observation_source estimate only)
        self.calls: list[str] = []

    # scene
    def reset(self, task, variant, seed):
        self.calls.append(f"reset:{variant}:{seed}")
        rng = np.random.default_rng(seed)
        w = {"D0": 0.04, "D1": 0.12}[variant]
        cy = rng.uniform(-0.4, 0.4)
        self.objects = {
            "cube": _T([0.5 + rng.uniform(-w, w), -0.12 + rng.uniform(-w, w), CUBE_HALF], Rotation.from_euler("z", cy)),
            "plate": _T([0.5 + rng.uniform(-w, w), 0.15 + rng.uniform(-w, w), 0.0],
                        Rotation.from_euler("z", rng.uniform(-0.4, 0.4))),
        }
        self.ee = _T([0.4, 0.0, 0.35], DOWN)
        self.grip = -1.0
        self.attached: np.ndarray | None = None
        self.q = np.zeros(7)
        return dict(self.objects)

    def observe(self) -> Observation:
        imgs = {"front": np.full((8, 8, 3), int(self.ee[0, 3] * 100) % 255, np.uint8)} if self.images else {}
        return Observation(self.ee.copy(), np.array([0.04, 0.04]) if self.grip < 0 else np.array([0.02, 0.02]),
                           self.q.copy(), {k: v.copy() for k, v in self.objects.items()}, imgs,
                           true_object_poses=None if self.no_truth else {k: v.copy() for k, v in self.objects.items()})

    def estimate_poses(self):
        self.calls.append("estimate")
        if self.perception_fails:
            return {}
        return {k: Pose.from_matrix(v) for k, v in self.objects.items()}

    def current_ee_pose(self) -> Pose:
        return Pose.from_matrix(self.ee)

    def current_q(self):
        return self.q.copy()

    def _move(self, T):
        self.ee = np.asarray(T, float).copy()
        self.q = self.q + 0.01
        if self.attached is not None:
            self.objects["cube"] = self.ee @ self.attached

    def plan_and_execute(self, target: Pose, mode, attached):
        self.calls.append(f"plan:{mode}:{attached}")
        if self.plan_status != "OK":
            return self.plan_status, []
        T0, T1 = self.ee.copy(), target.matrix()
        out = []
        for s in np.linspace(0, 1, 11)[1:]:
            T = T1.copy()
            T[:3, 3] = T0[:3, 3] + s * (T1[:3, 3] - T0[:3, 3])
            self._move(T)
            out.append(self.observe())
        return "OK", out

    def step(self, target: Pose, gripper: float) -> Observation:
        self._move(target.matrix())
        if gripper > 0 and self.grip <= 0:
            if np.linalg.norm(self.ee[:3, 3] - self.objects["cube"][:3, 3]) < 0.015:
                self.attached = np.linalg.inv(self.ee) @ self.objects["cube"]
        if gripper <= 0 and self.grip > 0 and self.attached is not None:
            self.attached = None
            cube = self.objects["cube"].copy()
            plate = self.objects["plate"]
            on_plate = np.linalg.norm(cube[:2, 3] - plate[:2, 3]) < 0.03
            cube[2, 3] = CUBE_HALF + (PLATE_TOP if on_plate else 0.0)
            self.objects["cube"] = cube
        self.grip = float(gripper)
        return self.observe()

    def task_success(self) -> bool:
        cube, plate = self.objects["cube"], self.objects["plate"]
        return (self.attached is None and np.linalg.norm(cube[:2, 3] - plate[:2, 3]) < 0.02
                and abs(cube[2, 3] - (PLATE_TOP + CUBE_HALF)) < 1e-6)

    def collided(self) -> bool:
        return self.collide


def _line(T0, T1, step=0.01):
    n = max(1, int(np.ceil(np.linalg.norm(T1[:3, 3] - T0[:3, 3]) / step)))
    out = []
    for s in np.arange(1, n + 1) / n:
        T = T1.copy()
        T[:3, 3] = T0[:3, 3] + s * (T1[:3, 3] - T0[:3, 3])
        out.append(T)
    return out


def scripted_demo(seed: int, name: str = "demo_0", source: str = "fake.mcap") -> DemoArrays:
    """Drive the fake world like a demonstrator and record the arrays a bag reader would give."""
    world = FakeWorld()
    world.reset("pick_place", "D0", seed)
    cube, plate = world.objects["cube"], world.objects["plate"]
    grasp = _T(cube[:3, 3], Rotation.from_matrix(cube[:3, :3]) * DOWN)
    place_pos = plate[:3, 3] + [0, 0, PLATE_TOP + CUBE_HALF]
    place = _T(place_pos, Rotation.from_matrix(grasp[:3, :3]))
    up = lambda T, h: _T(T[:3, 3] + [0, 0, h], Rotation.from_matrix(T[:3, :3]))  # noqa: E731
    plan: list[tuple[np.ndarray, float]] = []
    cur = world.ee
    for T1, g in ((up(grasp, 0.1), -1.0), (grasp, -1.0)):
        plan += [(T, g) for T in _line(cur, T1)]
        cur = T1
    plan += [(grasp, 1.0)] * 3
    for T1 in (up(grasp, 0.1), up(place, 0.1), place):
        plan += [(T, 1.0) for T in _line(cur, T1)]
        cur = T1
    plan += [(place, -1.0)] * 3
    plan += [(T, -1.0) for T in _line(cur, up(place, 0.08))]
    rec = {"t": [], "ee": [], "act": [], "g": [], "obj": {k: [] for k in world.objects}}
    for k, (T, g) in enumerate(plan):
        rec["t"].append(0.05 * k)
        rec["ee"].append(world.ee.copy())
        for oid, P in world.objects.items():
            rec["obj"][oid].append(P.copy())
        rec["act"].append(T)
        rec["g"].append(g)
        world.step(Pose.from_matrix(T), g)
    ee = np.array(rec["ee"])
    act = np.array(rec["act"])
    q = lambda M: Rotation.from_matrix(M[:, :3, :3]).as_quat()  # noqa: E731
    return DemoArrays(name=name, source=source, timestamps=np.array(rec["t"]), ee_positions=ee[:, :3, 3],
                      ee_quaternions=q(ee), gripper=np.array(rec["g"]),
                      object_positions={k: np.array(v)[:, :3, 3] for k, v in rec["obj"].items()},
                      object_quaternions={k: q(np.array(v)) for k, v in rec["obj"].items()},
                      action_positions=act[:, :3, 3], action_quaternions=q(act), variant="D0", scene_seed=seed)


def annotate(arrays: DemoArrays, task=FakeTask()) -> Annotation:
    from skillgen_ros.core.geometry import pose_arrays_to_matrices

    objs = {k: pose_arrays_to_matrices(arrays.object_positions[k], arrays.object_quaternions[k])
            for k in arrays.object_positions}
    return auto_annotate(task, arrays.name, arrays.ee_positions, arrays.gripper, objs, RULES)


def make_source_demos(n: int = 3, task=FakeTask()):
    out = []
    for i in range(n):
        arr = scripted_demo(100 + i, name=f"demo_{i}")
        out.append(source_demo_from_arrays(arr, annotate(arr, task), task))
    return out

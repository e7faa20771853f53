"""Privileged scripted solutions, driven through the OSC interface (absolute EE pose + gripper).

They read true object poses (privileged) and move with straight-line, constant-speed waypoints at
the control rate, so tests can show every task/variant is solvable through `step(pose, gripper)`.
Everything is parametric (ScriptParams: heights, speeds, grasp offsets, dwell times) so a
human-like demonstrator can reuse the phases with noise and different styles.

`env` is anything with ee_pose(), object_poses(), step(pose, gripper), task_success(),
control_hz and the current `scene` (SimWorld satisfies it; so can a ROS client wrapper).
EE convention: panda_grasptarget, z out of the gripper; top-down = z along world -z.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..errors import InvalidInputError
from ..geometry import Pose
from ..robot import TABLE_Z
from .spec import ObjectSpec, TaskSpec
from .suite import get_task

TOP_DOWN = Rotation.from_euler("x", np.pi)   # EE orientation at yaw 0 (home): x = world x, z down


@dataclass(frozen=True)
class ScriptParams:
    approach_height: float = 0.08     # pre-grasp / pre-place height above the goal (m)
    travel_height: float = 0.22       # minimum EE height for transit/transfer moves (m)
    clearance: float = 0.08           # extra height kept above fixtures/obstacles when travelling (m)
    speed: float = 0.25               # EE speed along straight segments (m/s)
    slow_speed: float = 0.08          # speed of the final approach / insertion (m/s)
    rot_speed: float = 1.5            # rad/s
    grasp_dwell: int = 10             # control periods with the gripper closing
    release_dwell: int = 8            # control periods with the gripper opening
    settle: int = 4                   # control periods holding each waypoint
    corrections: int = 2              # re-measure-and-correct passes above a place goal
    grasp_z_offset: float = 0.004     # grasp above the grasp keypoint (m, world z)
    milk_grasp_depth: float = 0.025   # grasp this far below the carton top (m)
    place_drop: float = 0.02          # release height of a placed object's bottom above its support (m)
    hand_clearance: float = 0.08     # keep the grasp point this far from other objects when placing (m)
    insert_pre: float = 0.05          # needle tip this far before the ring plane before inserting (m)
    insert_depth: float = 0.06        # and this far past it at the end: the 12 cm shaft's centre at the
    #                                   ring, MimicGen's success (mimicgen/envs/robosuite/threading.py)
    piece_grasp_depth: float = 0.02   # Three Piece Assembly: grasp this far below a piece's top (m)
    piece_drop: float = 0.008         # and release it this far above its seat (m)
    yaw_noise: float = 0.0            # hooks for a noisy demonstrator (rad, m); 0 = deterministic
    pos_noise: float = 0.0


@dataclass
class ScriptResult:
    success: bool
    steps: int
    actions: list = field(default_factory=list)  # (Pose, gripper) per control period


def top_down(position, yaw: float) -> Pose:
    return Pose(np.asarray(position, float), (Rotation.from_euler("z", yaw) * TOP_DOWN).as_quat())


def ee_yaw(pose: Pose) -> float:
    """Yaw of the EE x axis about world z."""
    x = pose.rotation.apply([1.0, 0.0, 0.0])
    return float(np.arctan2(x[1], x[0]))


def nearest_equivalent(yaw: float, reference: float, period: float) -> float:
    """yaw + k*period closest to `reference` (symmetric grasps / symmetric objects)."""
    return float(yaw + period * np.round((reference - yaw) / period))


def object_yaw(pose: Pose) -> float:
    return float(pose.rotation.as_euler("ZYX")[0])


class Scripter:
    """Issues waypoint motions on an env and records the commanded actions."""

    def __init__(self, env, params: ScriptParams, rng: np.random.Generator | None = None):
        self.env, self.params = env, params
        self.dt = 1.0 / env.control_hz
        self.target = env.ee_pose()
        self.gripper = -1.0
        self.actions: list = []
        self.rng = rng or np.random.default_rng(0)

    def command(self, pose: Pose, gripper: float) -> None:
        self.env.step(pose, gripper)
        self.actions.append((pose, gripper))
        self.target, self.gripper = pose, gripper

    def move(self, goal: Pose, speed: float | None = None, gripper: float | None = None) -> None:
        g = self.gripper if gripper is None else gripper
        v = speed or self.params.speed
        start = self.target
        dist = float(np.linalg.norm(goal.position - start.position))
        # yaw is interpolated numerically between the two (-pi, pi] yaws, i.e. through 0 and never
        # across +-pi, which keeps panda_joint7 away from its limits; the rest of the rotation is slerped
        y0, y1 = ee_yaw(start), ee_yaw(goal)
        rest = Rotation.concatenate([Rotation.from_euler("z", -y0) * start.rotation,
                                     Rotation.from_euler("z", -y1) * goal.rotation])
        ang = abs(y1 - y0) + float((rest[1] * rest[0].inv()).magnitude())
        n = max(1, int(np.ceil(max(dist / (v * self.dt), ang / (self.params.rot_speed * self.dt)))))
        slerp = Slerp([0.0, 1.0], rest)
        for k in range(1, n + 1):
            s = k / n
            R = Rotation.from_euler("z", y0 + s * (y1 - y0)) * slerp([s])[0]
            self.command(Pose(start.position + s * (goal.position - start.position), R.as_quat()), g)
        self.hold(self.params.settle, g)

    def hold(self, periods: int, gripper: float | None = None) -> None:
        for _ in range(periods):
            self.command(self.target, self.gripper if gripper is None else gripper)

    def lift_to(self, z: float) -> None:
        self.move(Pose([*self.target.position[:2], z], self.target.quaternion))

    def travel(self, goal: Pose, z: float) -> None:
        """Up to height z, across at z, then down to goal (approach speed for the last stretch)."""
        self.lift_to(max(z, self.target.position[2]))
        self.move(Pose([*goal.position[:2], max(z, goal.position[2])], goal.quaternion))
        self.move(goal)


def _travel_z(env, params: ScriptParams, carried_below: float = 0.0, exclude: tuple = ()) -> float:
    """Travel height clearing every fixture/obstacle top by `clearance` plus what hangs below the EE."""
    tops = [TABLE_Z]
    for o in env.scene.objects:
        if o.id not in exclude:
            pose = env.object_poses()[o.id]
            tops.append(float(np.max(_aabb_corners_world(o, pose)[:, 2])))
    return max(params.travel_height, max(tops) + params.clearance + carried_below)


def _aabb_corners_world(o: ObjectSpec, pose: Pose) -> np.ndarray:
    h = np.asarray(o.half_extents)
    c = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    return pose.rotation.apply(c) + pose.position


PIECE_GRASP_PERIOD = {"assembly_piece_1": np.pi, "assembly_piece_2": np.pi / 2}
MAX_EE_YAW = np.radians(100.0)  # |EE yaw| beyond this runs panda_joint7 into its limits
HAND_HALF_SPAN = 0.11   # panda_hand half width along the finger axis (m)


def hand_clearance(point_xy, yaw: float, others) -> float:
    """Smallest gap between the hand's footprint (a segment along the finger axis, EE y) and the
    bounding circles of `others` [(centre xy, radius)]; large if there are none."""
    axis = np.array([-np.sin(yaw), np.cos(yaw)])
    gaps = []
    for c, r in others:
        d = np.asarray(c) - np.asarray(point_xy)
        t = np.clip(d @ axis, -HAND_HALF_SPAN, HAND_HALF_SPAN)
        gaps.append(float(np.linalg.norm(d - t * axis)) - r)
    return min(gaps, default=1.0)


def grasp_pose(obj: ObjectSpec, pose: Pose, reference_yaw: float, params: ScriptParams, others=()) -> Pose:
    """Top-down grasp at the "handle" keypoint (or below the top), fingers closing across object y.

    Of the symmetric alternatives (every 180 deg, every 90 deg for the square carton) it takes the
    one closest to `reference_yaw` whose hand footprint clears `others` [(xy, radius)] by 2 cm."""
    if obj.type == "milk":
        point = pose.position + [0.0, 0.0, obj.half_extents[2] - params.milk_grasp_depth]
        period = np.pi / 2
    elif obj.type == "coffee_pod":   # round: at the reference yaw itself; at its "grasp" keypoint, 8 mm under the top
        return top_down(pose.rotation.apply(obj.keypoint("grasp")) + pose.position, reference_yaw)
    elif obj.type in PIECE_GRASP_PERIOD:   # across the piece's x (piece 1's ridge, piece 2's square knob)
        point = pose.rotation.apply(obj.keypoint("top")) + pose.position - [0.0, 0.0, params.piece_grasp_depth]
        period = PIECE_GRASP_PERIOD[obj.type]
        reference_yaw -= np.pi / 2   # compare in the object's frame: EE yaw = object yaw + 90 deg
    else:
        point = pose.rotation.apply(obj.keypoint("handle")) + pose.position + [0.0, 0.0, params.grasp_z_offset]
        period = np.pi
    base = nearest_equivalent(object_yaw(pose), reference_yaw, period)
    cands = [base + k * period for k in range(-2, 3) if abs(base + k * period - reference_yaw) <= np.pi / 2 + 1e-6]
    turn = np.pi / 2 if obj.type in PIECE_GRASP_PERIOD else 0.0
    yaw = min(cands, key=lambda y: (10.0 if hand_clearance(point[:2], y + turn, others) < 0.02 else 0.0)
              + abs(y - reference_yaw))
    return top_down(point, yaw + turn)


def pick(s: Scripter, obj_id: str, reference_yaw: float = 0.0) -> None:
    env, prm = s.env, s.params
    obj = next(o for o in env.scene.objects if o.id == obj_id)
    others = [(p.position[:2], o.footprint_radius) for o in env.scene.objects if o.id != obj_id
              for p in [env.object_poses()[o.id]]]
    g = grasp_pose(obj, env.object_poses()[obj_id], reference_yaw, prm, others)
    s.travel(Pose(g.position + [0, 0, prm.approach_height], g.quaternion), _travel_z(env, prm, exclude=(obj_id,)))
    s.move(g, prm.slow_speed, gripper=-1.0)
    s.hold(prm.grasp_dwell, 1.0)


class ScriptAborted(Exception):
    """The scripted plan cannot continue (e.g. the object slipped out of the gripper)."""


def _held(env, obj_id: str, max_dist: float = 0.10) -> Pose:
    """T_obj_ee of the held object; aborts if the object is no longer at the gripper."""
    obj, ee = env.object_poses()[obj_id], env.ee_pose()
    if np.linalg.norm(obj.position - ee.position) > max_dist:
        raise ScriptAborted(f"{obj_id} is not in the gripper")
    return obj.inverse() @ ee


def carry(s: Scripter, obj_id: str, goal_fn: Callable[[Pose], Pose], release: bool = True,
          pre_offset: np.ndarray | None = None) -> None:
    """Move the held object to goal_fn(current object pose) using the measured grasp transform."""
    env, prm = s.env, s.params
    obj = next(o for o in env.scene.objects if o.id == obj_id)
    T_obj_ee = _held(env, obj_id)
    goal_obj = goal_fn(env.object_poses()[obj_id])
    goal_ee = goal_obj @ T_obj_ee
    below = float(env.ee_pose().position[2] - np.min(_aabb_corners_world(obj, env.object_poses()[obj_id])[:, 2]))
    z = _travel_z(env, prm, carried_below=below, exclude=(obj_id,))
    pre = np.array([0.0, 0.0, prm.approach_height]) if pre_offset is None else pre_offset
    s.lift_to(z)
    s.travel(Pose(goal_ee.position + pre, goal_ee.quaternion), z)
    # the object may have swung or slipped in the grasp: re-measure and correct above the goal,
    # then finish slowly along the approach direction
    for _ in range(prm.corrections):
        s.hold(prm.settle)
        T_obj_ee = _held(env, obj_id)
        g = goal_obj @ T_obj_ee
        s.move(Pose(g.position + pre, g.quaternion), prm.slow_speed)
    T_obj_ee = _held(env, obj_id)
    s.move(goal_obj @ T_obj_ee, prm.slow_speed)
    if release:
        s.hold(prm.release_dwell, -1.0)
        s.lift_to(s.target.position[2] + prm.approach_height)


def _place_nut(nut: ObjectSpec, peg: ObjectSpec, env, prm: ScriptParams) -> Callable[[Pose], Pose]:
    """Nut goal: ring centre on the peg axis, dropped from just above the table. Of the nut yaws that
    fit (any for a round peg, four for a square one; candidates within +-90 deg of the current yaw),
    prefer one whose handle (and so the hand) stays clear of other objects, then the smallest EE yaw."""
    def goal(nut_pose: Pose) -> Pose:
        peg_pose = env.object_poses()[peg.id]
        yaw0, e = object_yaw(nut_pose), ee_yaw(env.ee_pose())
        base = nearest_equivalent(object_yaw(peg_pose), yaw0, np.pi / 2) if peg.symmetry == "z4" else yaw0
        others = [(p.position[:2], o.footprint_radius) for o in env.scene.objects
                  if o.id not in (nut.id, peg.id) for p in [env.object_poses()[o.id]]]
        handle = nut.keypoint("handle") - nut.keypoint("ring_center")

        def cost(y: float) -> float:
            h = peg_pose.position[:2] + Rotation.from_euler("z", y).apply(handle)[:2]
            clear = min((np.linalg.norm(h - c) - r for c, r in others), default=1.0)
            ee_after = abs(e + (y - yaw0))
            return (100.0 if ee_after > MAX_EE_YAW else 0.0) + (10.0 if clear < prm.hand_clearance else 0.0) + ee_after
        yaw = min((base + k * np.pi / 2 for k in (-1, 0, 1)), key=cost)
        R = Rotation.from_euler("z", yaw)
        bottom = peg_pose.position[2] - peg.half_extents[2]
        ring = np.array([*peg_pose.position[:2], bottom + nut.half_extents[2] + prm.place_drop + 0.02])
        return Pose(ring - R.apply(nut.keypoint("ring_center")), R.as_quat())
    return goal


def _place_in_bin(obj: ObjectSpec, bin_: ObjectSpec, env, prm: ScriptParams) -> Callable[[Pose], Pose]:
    def goal(obj_pose: Pose) -> Pose:
        b = env.object_poses()[bin_.id]
        floor = b.rotation.apply(bin_.keypoint("floor_center")) + b.position
        R = Rotation.from_euler("z", object_yaw(obj_pose))
        return Pose([*floor[:2], floor[2] + obj.half_extents[2] + prm.place_drop], R.as_quat())
    return goal


def _seat_piece(piece: ObjectSpec, target: ObjectSpec, seat_z: float, period: float, env,
                prm: ScriptParams) -> Callable[[Pose], Pose]:
    """A piece's goal: centred over target, turned to the target's yaw (mod period) nearest its own, its
    centre prm.piece_drop above seat_z (piece 1 on the table in the base's hole, piece 2's legs on the base)."""
    def goal(piece_pose: Pose) -> Pose:
        t = env.object_poses()[target.id]
        R = Rotation.from_euler("z", nearest_equivalent(object_yaw(t), object_yaw(piece_pose), period))
        return Pose([*t.position[:2], seat_z + prm.piece_drop], R.as_quat())
    return goal


def _thread(s: Scripter, needle: ObjectSpec, tripod: ObjectSpec) -> None:
    env, prm = s.env, s.params
    tp = env.object_poses()[tripod.id]
    c = tp.rotation.apply(tripod.keypoint("ring_center")) + tp.position
    axis = tp.rotation.apply([1.0, 0.0, 0.0])
    axis = np.array([axis[0], axis[1], 0.0]) / np.linalg.norm(axis[:2])
    tip_local = needle.keypoint("tip")
    # insertion direction: the one needing the smaller EE yaw change, EE yaw kept inside +-2 rad
    n_yaw = object_yaw(env.object_poses()[needle.id])
    e_yaw = ee_yaw(env.ee_pose())
    best = None
    for d in (axis, -axis):
        delta = (np.arctan2(d[1], d[0]) - n_yaw + np.pi) % (2 * np.pi) - np.pi
        cost = abs(delta) + (10.0 if abs(e_yaw + delta) > 2.0 else 0.0)
        if best is None or cost < best[0]:
            best = (cost, d, n_yaw + delta)
    _, d, yaw = best
    R = Rotation.from_euler("z", yaw)

    def needle_goal(depth: float) -> Callable[[Pose], Pose]:
        tip = c + d * depth
        return lambda _p: Pose(tip - R.apply(tip_local), R.as_quat())

    carry(s, needle.id, needle_goal(-prm.insert_pre), release=False, pre_offset=np.zeros(3))
    T_obj_ee = _held(env, needle.id)
    s.move(needle_goal(prm.insert_depth)(None) @ T_obj_ee, prm.slow_speed)
    s.hold(prm.settle)


def solve(env, params: ScriptParams | None = None, rng: np.random.Generator | None = None) -> ScriptResult:
    """Run the privileged scripted solution of env.scene's task; returns success and the actions."""
    prm = params or ScriptParams()
    if env.scene is None:
        raise InvalidInputError("reset the scene before solving", "NO_SCENE")
    task: TaskSpec = get_task(env.scene.task)
    s = Scripter(env, prm, rng)
    s.hold(2, -1.0)
    O = {o.id: o for o in env.scene.objects}
    try:
        _run(task, s, O, env, prm)
    except ScriptAborted:
        pass
    s.hold(prm.settle)
    return ScriptResult(bool(env.task_success()), len(s.actions), s.actions)


def _run(task: TaskSpec, s: Scripter, O: dict, env, prm: ScriptParams) -> None:
    if task.name in ("Square", "NutAssembly"):
        pairs = [("square_nut", "square_peg")] + ([("round_nut", "round_peg")] if task.name == "NutAssembly" else [])
        for nut, peg in pairs:
            pick(s, nut)
            carry(s, nut, _place_nut(O[nut], O[peg], env, prm))
    elif task.name == "PickPlace":
        pick(s, "milk")
        carry(s, "milk", _place_in_bin(O["milk"], O["bin"], env, prm))
    elif task.name == "Threading":
        pick(s, "needle")
        _thread(s, O["needle"], O["tripod"])
    elif task.name == "ThreePieceAssembly":
        b, p1, p2 = O["base"], O["piece_1"], O["piece_2"]
        pick(s, "piece_1")
        carry(s, "piece_1", _seat_piece(p1, b, TABLE_Z + p1.half_extents[2], np.pi / 2, env, prm))
        pick(s, "piece_2")
        seat = TABLE_Z + 2 * b.half_extents[2] + p2.half_extents[2]
        carry(s, "piece_2", _seat_piece(p2, p1, seat, np.pi, env, prm))
    elif task.name == "Coffee":
        m, pod = O["coffee_machine"], O["coffee_pod"]
        # fingers across machine x, clear of the hinge and the holder's bracket (as the demonstrator)
        pick(s, "coffee_pod", nearest_equivalent(object_yaw(env.object_poses()[m.id]) + np.pi / 2, 0.0, np.pi))
        carry(s, "coffee_pod", _pod_into_holder(pod, m, env), pre_offset=np.array([0.0, 0.0, 0.03]))
        _close_lid(s, env.object_poses()[m.id])
    elif task.name == "CoffeePreparation":
        from . import scripted_coffee_prep   # its own module (it uses this one's primitives)
        scripted_coffee_prep.run(s)


# Coffee: the pod is let go with its bottom this far into the holder (it slides the rest of the way down); the
# open hand pushes the open lid shut from behind at this machine-frame height, along machine +y from / to
# (as the human-like demonstrator, core/demonstrator/human_like.py)
POD_RELEASE_IN = 0.025
LID_PUSH_Z, LID_PUSH_FROM, LID_PUSH_TO = 0.16, -0.03, 0.11


def _pod_into_holder(pod: ObjectSpec, machine: ObjectSpec, env) -> Callable[[Pose], Pose]:
    def goal(pod_pose: Pose) -> Pose:
        m = env.object_poses()[machine.id]
        top = m.rotation.apply(machine.keypoint("holder_top")) + m.position
        return Pose([*top[:2], top[2] - POD_RELEASE_IN + pod.half_extents[2]], pod_pose.quaternion)
    return goal


def _close_lid(s: Scripter, m: Pose) -> None:
    """The open hand, fingers in a row along machine y, sweeps from behind the lid over the hinge: the lid
    tips past upright and falls shut."""
    q = top_down(np.zeros(3), nearest_equivalent(object_yaw(m), ee_yaw(s.target), np.pi)).quaternion

    def at(y: float, z: float) -> Pose:
        return Pose(m.rotation.apply([0.0, y, z]) + m.position, q)
    s.lift_to(s.target.position[2] + 0.10)
    s.move(at(LID_PUSH_FROM, LID_PUSH_Z + 0.09))
    s.move(at(LID_PUSH_FROM, LID_PUSH_Z), s.params.slow_speed)
    s.move(at(LID_PUSH_TO, LID_PUSH_Z), s.params.slow_speed)
    s.lift_to(s.target.position[2] + 0.10)


def with_params(**kw) -> ScriptParams:
    return replace(ScriptParams(), **kw)

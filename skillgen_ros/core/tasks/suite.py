"""The task suite: Square, PickPlace, NutAssembly, Threading (+ clutter variants of Square/PickPlace).

Reset regions are the paper's appendix (MimicGen/SkillMimicGen D0/D1/D2) scaled to a Panda whose
base is at the world origin on the table: objects live in roughly x in [0.38, 0.70] m,
y in [-0.30, 0.30] m. "clutter" = D1 regions plus one large obstacle near the workspace centre.
docs/tasks.md lists every region (generated from this file by `regions_markdown()`).
Skill object_id is the skill's reference object (the frame its motion is expressed in): the
object grasped for a grasp skill, the target fixture for a place/insert skill.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..errors import UnknownTaskError
from ..geometry import Pose
from . import objects as O
from .spec import ObjectSpec, Region, SkillSpec, TaskSpec

PI = np.pi
FULL = (-PI, PI)


def _deg(a: float, b: float) -> tuple[float, float]:
    return (float(np.radians(a)), float(np.radians(b)))


def _world(pose: Pose, local) -> np.ndarray:
    return pose.rotation.apply(np.asarray(local, float)) + pose.position


def nut_on_peg(nut: ObjectSpec, peg: ObjectSpec, poses: Mapping[str, Pose], xy_tol: float = 0.02) -> bool:
    """The nut's ring centre is within xy_tol of the peg axis and below the peg's top."""
    c = _world(poses[nut.id], nut.keypoint("ring_center"))
    peg_pose = poses[peg.id]
    top = _world(peg_pose, peg.keypoint("top"))
    return bool(np.hypot(*(c[:2] - peg_pose.position[:2])) < xy_tol and c[2] < top[2] - 0.01)


def object_in_bin(obj: ObjectSpec, bin_: ObjectSpec, poses: Mapping[str, Pose]) -> bool:
    """The object's centre is inside the bin's inner footprint and low enough to be resting in it."""
    b = poses[bin_.id]
    local = b.rotation.inv().apply(poses[obj.id].position - b.position)
    floor = _world(b, bin_.keypoint("floor_center"))[2]
    return bool(abs(local[0]) < O.BIN_INNER_HALF and abs(local[1]) < O.BIN_INNER_HALF
                and poses[obj.id].position[2] < floor + 2 * obj.half_extents[2] + 0.02)


def needle_through_ring(needle: ObjectSpec, tripod: ObjectSpec, poses: Mapping[str, Pose]) -> bool:
    """The shaft crosses the ring plane inside the opening (tip on one side, shaft base on the other)."""
    t = poses[tripod.id]
    c = _world(t, tripod.keypoint("ring_center"))
    axis = t.rotation.apply([1.0, 0.0, 0.0])
    b = _world(poses[needle.id], needle.keypoint("shaft_base"))
    tip = _world(poses[needle.id], needle.keypoint("tip"))
    sb, st = float((b - c) @ axis), float((tip - c) @ axis)
    if sb * st >= 0.0:
        return False
    p = b + (tip - b) * sb / (sb - st)
    local = t.rotation.inv().apply(p - c)
    return bool(abs(local[1]) < O.RING_OPENING_HALF and abs(local[2]) < O.RING_OPENING_HALF)


def _fixed(x: float, y: float, yaw: float = 0.0) -> Region:
    return Region((x, x), (y, y), (yaw, yaw))


CLUTTER_REGION = Region((0.50, 0.58), (-0.06, 0.06), _deg(-45, 45))


def _square() -> TaskSpec:
    nut, peg = O.square_nut(), O.square_peg()
    d1 = {"square_peg": Region((0.48, 0.66), (0.04, 0.24)), "square_nut": Region((0.40, 0.53), (-0.30, -0.04), FULL)}
    table = {
        "D0": {"square_peg": _fixed(0.60, 0.12), "square_nut": Region((0.48, 0.485), (-0.215, -0.10), FULL)},
        "D1": d1,
        "D2": {"square_peg": Region((0.40, 0.68), (-0.22, 0.22), _deg(-45, 45)),
               "square_nut": Region((0.40, 0.68), (-0.25, 0.25), FULL)},
        "clutter": {**d1, "obstacle": CLUTTER_REGION},
    }
    skills = (SkillSpec(0, "square_nut", "grasp_nut", "transit"),
              SkillSpec(1, "square_peg", "place_on_peg", "transfer", "square_nut"))
    return TaskSpec("Square", (nut, peg), skills, ("D0", "D1", "D2", "clutter"), table,
                    lambda p: nut_on_peg(nut, peg, p), O.obstacle())


def _pick_place() -> TaskSpec:
    m, b = O.milk(), O.bin_()
    d1 = {"bin": _fixed(0.55, 0.19), "milk": Region((0.42, 0.62), (-0.30, -0.08), _deg(-45, 45))}
    table = {
        "D0": {"bin": _fixed(0.55, 0.19), "milk": Region((0.50, 0.56), (-0.20, -0.14), _deg(-45, 45))},
        "D1": d1,
        "D2": {"bin": Region((0.45, 0.65), (0.14, 0.24), _deg(-45, 45)),
               "milk": Region((0.40, 0.66), (-0.30, -0.04), _deg(-45, 45))},
        "clutter": {**d1, "obstacle": CLUTTER_REGION},
    }
    skills = (SkillSpec(0, "milk", "grasp_milk", "transit"), SkillSpec(1, "bin", "place_in_bin", "transfer", "milk"))
    return TaskSpec("PickPlace", (m, b), skills, ("D0", "D1", "D2", "clutter"), table,
                    lambda p: object_in_bin(m, b, p), O.obstacle())


def _nut_assembly() -> TaskSpec:
    sn, rn, sp, rp = O.square_nut(), O.round_nut(), O.square_peg(), O.round_peg()
    table = {
        "D0": {"square_peg": _fixed(0.64, 0.12), "round_peg": _fixed(0.64, -0.12),
               "square_nut": Region((0.42, 0.425), (0.10, 0.215), FULL),
               "round_nut": Region((0.42, 0.425), (-0.215, -0.10), FULL)},
        "D1": {"square_peg": Region((0.58, 0.68), (0.02, 0.22)), "round_peg": Region((0.58, 0.68), (-0.22, -0.02)),
               "square_nut": Region((0.38, 0.48), (-0.25, 0.25), FULL),
               "round_nut": Region((0.38, 0.48), (-0.25, 0.25), FULL)},
        "D2": {name: Region((0.38, 0.68), (-0.28, 0.28), FULL if "nut" in name else _deg(-45, 45))
               for name in ("square_peg", "round_peg", "square_nut", "round_nut")},
    }
    skills = (SkillSpec(0, "square_nut", "grasp_square_nut", "transit"),
              SkillSpec(1, "square_peg", "place_on_square_peg", "transfer", "square_nut"),
              SkillSpec(2, "round_nut", "grasp_round_nut", "transit"),
              SkillSpec(3, "round_peg", "place_on_round_peg", "transfer", "round_nut"))
    return TaskSpec("NutAssembly", (sn, rn, sp, rp), skills, ("D0", "D1", "D2"), table,
                    lambda p: nut_on_peg(sn, sp, p) and nut_on_peg(rn, rp, p))


def _threading() -> TaskSpec:
    nd, tp = O.needle(), O.tripod()
    table = {
        "D0": {"tripod": _fixed(0.58, 0.14, PI / 2), "needle": Region((0.44, 0.56), (-0.20, -0.12), _deg(60, 120))},
        "D1": {"tripod": Region((0.48, 0.64), (0.10, 0.20), _deg(30, 150)),
               "needle": Region((0.42, 0.62), (-0.22, -0.12), _deg(-30, 210))},
        "D2": {"tripod": Region((0.48, 0.64), (-0.20, -0.10), _deg(-150, -30)),
               "needle": Region((0.42, 0.62), (0.12, 0.22), _deg(-210, 30))},
    }
    skills = (SkillSpec(0, "needle", "grasp_needle", "transit"),
              SkillSpec(1, "tripod", "thread_tripod", "transfer", "needle"))
    return TaskSpec("Threading", (nd, tp), skills, ("D0", "D1", "D2"), table, lambda p: needle_through_ring(nd, tp, p))


_BUILDERS = {"Square": _square, "PickPlace": _pick_place, "NutAssembly": _nut_assembly, "Threading": _threading}
TASK_NAMES: tuple[str, ...] = tuple(_BUILDERS)
_CACHE: dict[str, TaskSpec] = {}


def get_task(name: str) -> TaskSpec:
    """The TaskSpec for `name` (one of TASK_NAMES); UnknownTaskError otherwise."""
    if name not in _BUILDERS:
        raise UnknownTaskError(f"unknown task {name!r}; known: {list(TASK_NAMES)}")
    if name not in _CACHE:
        _CACHE[name] = _BUILDERS[name]()
    return _CACHE[name]


def regions_markdown() -> str:
    """The docs/tasks.md table of every variant's reset regions (regenerate when regions change)."""
    rows = ["| task | variant | object | x range (m) | y range (m) | yaw range (deg) |", "|---|---|---|---|---|---|"]
    for name in TASK_NAMES:
        t = get_task(name)
        for v in t.variants:
            for oid, r in t.regions(v).items():
                yaw = np.degrees(r.yaw)
                rows.append(f"| {name} | {v} | {oid} | [{r.x[0]:.3f}, {r.x[1]:.3f}] | [{r.y[0]:.3f}, {r.y[1]:.3f}] "
                            f"| [{yaw[0]:.0f}, {yaw[1]:.0f}] |")
    return "\n".join(rows)

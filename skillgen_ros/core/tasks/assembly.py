"""Three Piece Assembly's objects and success rule: MimicGen's base, piece 1 and piece 2.

Reference: NVlabs/mimicgen `mimicgen/envs/robosuite/three_piece_assembly.py` (ThreePieceAssembly:
`_get_piece_patterns`, `_load_model`, `_get_piece_densities`, `_check_first_piece_is_assembled`,
`_check_second_piece_is_assembled`) and `mimicgen/models/robosuite/objects/composite/box_pattern_object.py`.

A BoxPatternObject is a (z, x, y) grid of cubes of half size `unit_size`, cell (k, i, j) centred at
(-total + unit + 2 unit (i, j, k)): the body origin is the centre of the whole grid's box, which is our
object frame (the AABB centre) for all three objects. The patterns (with MimicGen's `pick = 0` and
offsets 1):
- base (unit 0.019, 3.8 cm cubes): one layer of 5 x 5 with the centre 3 x 3 empty: a 19 x 19 x 3.8 cm
  frame around an 11.4 cm square hole;
- piece 1 (unit 0.017, 3.4 cm cubes): a full 3 x 3 bottom layer (10.2 x 10.2 x 3.4 cm plate) and, in the
  two layers above, the middle x row: a ridge 3.4 cm across (object x), 10.2 cm long (object y), 6.8 cm tall;
- piece 2 (unit 0.02, 4 cm cubes): two layers with the middle x row empty (two legs 4 x 12 x 8 cm and a
  4 cm slot along object y, 8 cm deep), a full 3 x 3 layer, and one centre cube on top (the knob).
We merge each run of cubes into one box (same solid, fewer pybullet shapes). Piece 1's plate goes into the
base's hole with 6 mm of clearance a side; piece 2's slot takes piece 1's ridge with 3 mm a side and its
legs come to rest on the base's top.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .objects import _build
from .shapes import box
from .spec import ObjectSpec, SceneState

# three_piece_assembly.py _load_model: piece_1_size 0.017, piece_2_size 0.02, base_size 0.019 (unit half sizes)
PIECE_1_UNIT = 0.017
PIECE_2_UNIT = 0.02
BASE_UNIT = 0.019
# _get_piece_densities: base 10000 ("changed to make base piece heavier and task easier"), pieces 100 (kg/m^3)
DENSITY = {"base": 10000.0, "piece_1": 100.0, "piece_2": 100.0}
# _check_first_piece_is_assembled(xy_thresh=0.02), _check_second_piece_is_assembled(xy_thresh=0.02, z_thresh=0.02);
# z_correct = base z + piece_2_size * 4
XY_THRESH = 0.02
Z_THRESH = 0.02
Z_CORRECT_ABOVE_BASE = PIECE_2_UNIT * 4
# robosuite's _check_grasp needs both finger pads touching the piece. A SceneState has no contacts, so a piece
# counts as held when the gripper is commanded closed with the grasp point inside the piece's box grown by this.
HELD_MARGIN = 0.01

BASE_HALF = 5 * BASE_UNIT        # 0.095: 19 cm square
BASE_HOLE_HALF = 3 * BASE_UNIT   # 0.057: 11.4 cm square hole
PIECE_1_HALF = 3 * PIECE_1_UNIT  # 0.051: a 10.2 cm cube overall
PIECE_2_HALF_XY, PIECE_2_HALF_Z = 3 * PIECE_2_UNIT, 4 * PIECE_2_UNIT   # 12 x 12 x 16 cm overall
SLOT_HALF = PIECE_2_UNIT         # 0.02: the 4 cm slot
RIDGE_HALF = PIECE_1_UNIT        # 0.017: the 3.4 cm ridge


def _mass(obj_id: str, parts) -> float:
    return DENSITY[obj_id] * sum(8 * float(np.prod(p.size)) for p in parts)


@lru_cache(maxsize=None)
def base(obj_id: str = "base") -> ObjectSpec:
    """The 19 x 19 x 3.8 cm frame with an 11.4 cm square hole (8.8 kg: MimicGen's density 10000)."""
    u, h, c = BASE_UNIT, BASE_HALF, BASE_HOLE_HALF + BASE_UNIT
    parts = (box(u, h, u, x=c), box(u, h, u, x=-c), box(BASE_HOLE_HALF, u, u, y=c), box(BASE_HOLE_HALF, u, u, y=-c))
    kp = {"body_origin": (0, 0, 0), "top": (0, 0, u)}
    return _build(obj_id, "assembly_base", parts, kp, fixture=False, symmetry="z4", mass=_mass("base", parts),
                  color=(0.55, 0.2, 0.15, 1.0))


@lru_cache(maxsize=None)
def piece_1(obj_id: str = "piece_1") -> ObjectSpec:
    """A 10.2 cm square plate (3.4 cm thick) under a 3.4 cm wide ridge along object y; grasped across the ridge."""
    u, h = PIECE_1_UNIT, PIECE_1_HALF
    parts = (box(h, h, u, z=-h + u), box(u, h, 2 * u, z=-h + 4 * u))
    # grasp: 2 cm below the top, where the demonstrator closes on the ridge
    kp = {"body_origin": (0, 0, 0), "top": (0, 0, h), "bottom": (0, 0, -h), "grasp": (0, 0, h - 0.02)}
    return _build(obj_id, "assembly_piece_1", parts, kp, fixture=False, symmetry="z2", mass=_mass("piece_1", parts),
                  color=(0.75, 0.3, 0.2, 1.0))


@lru_cache(maxsize=None)
def piece_2(obj_id: str = "piece_2") -> ObjectSpec:
    """Two legs either side of a 4 cm slot along object y, a 12 cm square plate on them, a 4 cm knob on top."""
    u, hxy, hz = PIECE_2_UNIT, PIECE_2_HALF_XY, PIECE_2_HALF_Z
    leg = (u, hxy, 2 * u)
    parts = (box(*leg, x=2 * u, z=-hz + 2 * u), box(*leg, x=-2 * u, z=-hz + 2 * u),
             box(hxy, hxy, u, z=-hz + 5 * u), box(u, u, u, z=hz - u))
    kp = {"body_origin": (0, 0, 0), "top": (0, 0, hz), "bottom": (0, 0, -hz), "grasp": (0, 0, hz - 0.02)}
    return _build(obj_id, "assembly_piece_2", parts, kp, fixture=False, symmetry="z2", mass=_mass("piece_2", parts),
                  color=(0.85, 0.45, 0.25, 1.0))


def held(obj: ObjectSpec, state: SceneState) -> bool:
    """The hand holds obj: gripper commanded closed, grasp point within HELD_MARGIN of the object's box."""
    if state.gripper <= 0.0:
        return False
    pose = state.poses[obj.id]
    local = pose.rotation.inv().apply(np.asarray(state.ee_position, float) - pose.position)
    return bool(np.all(np.abs(local) <= np.asarray(obj.half_extents) + HELD_MARGIN))


def first_piece_assembled(b: ObjectSpec, p1: ObjectSpec, state: SceneState) -> bool:
    """MimicGen _check_first_piece_is_assembled: piece 1 within 2 cm of the base in x-y, not held."""
    pb, q1 = state.poses[b.id].position, state.poses[p1.id].position
    return bool(np.linalg.norm(q1[:2] - pb[:2]) < XY_THRESH) and not held(p1, state)


def assembled(b: ObjectSpec, p1: ObjectSpec, p2: ObjectSpec, state: SceneState) -> bool:
    """MimicGen _check_second_piece_is_assembled (the task's success): the first piece assembled, piece 2
    within 2 cm of piece 1 in x-y, its centre within 2 cm of base z + 8 cm, and not held."""
    pb, q1, q2 = (state.poses[o.id].position for o in (b, p1, p2))
    return (first_piece_assembled(b, p1, state) and bool(np.linalg.norm(q1[:2] - q2[:2]) < XY_THRESH)
            and bool(abs(q2[2] - (pb[2] + Z_CORRECT_ABOVE_BASE)) < Z_THRESH) and not held(p2, state))

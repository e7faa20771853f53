"""The task objects: nuts with handles, pegs, milk carton, bin, needle, tripod, obstacle, and Three Piece
Assembly's base and pieces (core/tasks/assembly.py).

Dimensions are robosuite 1.5.2's and NVlabs/mimicgen's (each constant names its file and value); the
square nut keeps our handle/wall (its hole and the peg already match robosuite). Each builder returns
an ObjectSpec whose OBJ mesh (core/tasks/meshes/<type>.obj) is written from the same primitives the
simulator uses. Keypoints name the features scripted solvers and success predicates need (object
frame); "body_origin" is where the reference model's body origin lies (robosuite's nut bodies sit at
the ring centre), the point reset regions and success rules are stated for. An articulated object's mesh
also shows its links at their reset values (what perception fits at the start of a task); its
half_extents are its fixed base's.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from .articulation import BASE, posed_link_parts
from .shapes import Part, aabb, box, cylinder, recentre, write_obj
from .spec import ObjectSpec

MESH_DIR = Path(__file__).resolve().parent / "meshes"

NUT_WALL = 0.012
NUT_HALF_THICK = 0.01        # robosuite square-nut.xml / round-nut.xml geom half z 0.01 (2 cm thick)
NUT_HANDLE_LEN = 0.055
NUT_HANDLE_HALF_WIDTH = 0.01
# robosuite models/assets/arenas/pegs_arena.xml: pegs are half 0.1 tall at body z 0.85 on a table whose
# top is at 0.82 (nut_assembly.py table_offset), so 0.85 + 0.1 - 0.82 = 0.13 m stands above the table.
PEG_HEIGHT = 0.13
PEG_HALF_HEIGHT = PEG_HEIGHT / 2
SQUARE_PEG_HALF = 0.016      # pegs_arena.xml peg1 box size 0.016 0.016 (3.2 cm square)
SQUARE_HOLE_HALF = 0.023     # square-nut.xml walls at +-0.03325, half 0.0105 thick: hole 2 x 0.02275 = 4.55 cm
ROUND_PEG_RADIUS = 0.02      # pegs_arena.xml peg2 cylinder size 0.02 (4 cm)
# robosuite round-nut.xml: an octagon of 8 boxes (half 0.01125 x 0.0225 x 0.01) at 0.04245 from the centre,
# every 45 deg; inscribed hole 2 x (0.04245 - 0.01125) = 6.24 cm; handle half 0.02525 x 0.015875 at x 0.06.
ROUND_WALL_CENTER = 0.04245
ROUND_WALL_HALF = (0.01125, 0.0225)
ROUND_HOLE_RADIUS = ROUND_WALL_CENTER - ROUND_WALL_HALF[0]   # 0.0312 (inscribed)
ROUND_HANDLE_X, ROUND_HANDLE_HALF = 0.06, (0.02525, 0.015875)
# NVlabs/mimicgen mimicgen/models/robosuite/objects/composite/needle.py: needle_size [0.005, 0.06, 0.005]
# (a 1 x 1 x 12 cm shaft) on a handle_size [0.02, 0.02, 0.02] cube (4 cm), shaft centred on the handle axis.
NEEDLE_SHAFT_HALF = 0.005
NEEDLE_SHAFT_HALF_LEN = 0.06
NEEDLE_HANDLE_HALF = 0.02
# .../composite/ring_tripod.py: a 6 x 6 pattern of unit_size [0.005, 0.002, 0.002] boxes with the inner 4 x 4
# empty: a ring 1 cm thick along object x, 2.4 cm outside, with a 1.6 cm square hole; ring_size [0.005, 0.012,
# 0.012]. total_size (0.05, 0.05, 0.1); ring cells centred 0.078..0.098 above the body origin (ring centre
# 0.088), i.e. 0.188 above the table; post 0.005 half on a 0.1 x 0.1 x 0.01 plate at z -0.02..-0.01; three
# capsule legs (r 0.01, half 0.03) tilted 30 deg.
MIMICGEN_DENSITY = 100.0   # needle.py / ring_tripod.py base_args "density": 100.0 (kg/m^3)
# ring_tripod.py: ring geoms friction (0.3, 5e-3, 1e-4), "low friction to ensure easy insertion" (needle.py gives
# its shaft 0.3 too). MuJoCo takes the larger of two frictions, Bullet their product: the ring's 0.3 against
# the needle's 1.0 (its handle is grasped) gives the reference's 0.3 at the ring.
RING_FRICTION = 0.3
RING_UNIT = (0.005, 0.002, 0.002)
RING_SIZE = (0.005, 0.012, 0.012)            # ring_size: RING_SIZE[1] is MimicGen's success radius
RING_OPENING_HALF = RING_SIZE[1] - 2 * RING_UNIT[1]   # 0.008: 1.6 cm hole
TRIPOD_HALF = (0.05, 0.05, 0.1)
RING_CENTER_Z = 0.088                        # above the tripod body origin (-0.1 + 0.176 + 0.002 + 0.01)
RING_HEIGHT = TRIPOD_HALF[2] + RING_CENTER_Z  # 0.188: ring centre above the table
BIN_INNER_HALF = 0.09
BIN_WALL_HEIGHT = 0.06


def _build(obj_id: str, type_: str, parts: tuple[Part, ...], keypoints: dict, *, fixture: bool,
           symmetry: str, mass: float, color, friction: float = 1.0, links=(), joints=()) -> ObjectSpec:
    """Recentre the (base) parts on their AABB, moving keypoints and base joints' origins with them."""
    parts, shift = recentre(parts)
    lo, hi = aabb(parts)
    kps = tuple((k, tuple(float(x) for x in np.asarray(v) + shift)) for k, v in keypoints.items())
    joints = tuple(j.shifted(shift) if j.parent == BASE else j for j in joints)
    path = MESH_DIR / f"{type_}.obj"
    write_obj(parts + posed_link_parts(links, joints), path, type_)
    return ObjectSpec(id=obj_id, type=type_, mesh_path=str(path), half_extents=tuple(float(x) for x in (hi - lo) / 2),
                      is_fixture=fixture, symmetry=symmetry, mass=0.0 if fixture else mass, parts=parts,
                      color=tuple(color), friction=friction, keypoints=kps, links=tuple(links), joints=joints)


def center_of_mass(parts: tuple[Part, ...]) -> np.ndarray:
    """Volume-weighted centroid of the parts (uniform density), in the object frame."""
    vols = np.array([8 * np.prod(p.size) if p.kind == "box" else np.pi * p.size[0] ** 2 * 2 * p.size[1]
                     for p in parts])
    pos = np.array([p.position for p in parts])
    return (vols[:, None] * pos).sum(axis=0) / vols.sum()


def _nut_handle(outer: float) -> Part:
    return box(NUT_HANDLE_LEN / 2, NUT_HANDLE_HALF_WIDTH, NUT_HALF_THICK, x=outer + NUT_HANDLE_LEN / 2)


@lru_cache(maxsize=None)
def square_nut(obj_id: str = "square_nut") -> ObjectSpec:
    h, w, t = SQUARE_HOLE_HALF, NUT_WALL, NUT_HALF_THICK
    parts = (box(w / 2, h + w, t, x=h + w / 2), box(w / 2, h + w, t, x=-(h + w / 2)),
             box(h, w / 2, t, y=h + w / 2), box(h, w / 2, t, y=-(h + w / 2)), _nut_handle(h + w))
    kp = {"ring_center": (0, 0, 0), "body_origin": (0, 0, 0), "handle": (h + w + NUT_HANDLE_LEN / 2, 0, 0)}
    return _build(obj_id, "square_nut", parts, kp, fixture=False, symmetry="none", mass=0.05,
                  color=(0.75, 0.55, 0.2, 1.0))


@lru_cache(maxsize=None)
def round_nut(obj_id: str = "round_nut") -> ObjectSpec:
    """robosuite's RoundNut (round-nut.xml): octagon ring, 6.24 cm inscribed hole, handle along +x."""
    c, (hx, hy), t = ROUND_WALL_CENTER, ROUND_WALL_HALF, NUT_HALF_THICK
    parts = tuple(box(hx, hy, t, x=c * np.cos(a), y=c * np.sin(a), yaw=a) for a in np.arange(8) * np.pi / 4)
    parts += (box(*ROUND_HANDLE_HALF, t, x=ROUND_HANDLE_X),)
    outer = c + hx  # the handle's free part starts at the octagon's outer face (0.0537)
    kp = {"ring_center": (0, 0, 0), "body_origin": (0, 0, 0),
          "handle": ((outer + ROUND_HANDLE_X + ROUND_HANDLE_HALF[0]) / 2, 0, 0)}
    return _build(obj_id, "round_nut", parts, kp, fixture=False, symmetry="none", mass=0.05,
                  color=(0.5, 0.5, 0.55, 1.0))


@lru_cache(maxsize=None)
def square_peg(obj_id: str = "square_peg") -> ObjectSpec:
    parts = (box(SQUARE_PEG_HALF, SQUARE_PEG_HALF, PEG_HALF_HEIGHT),)
    return _build(obj_id, "square_peg", parts, {"top": (0, 0, PEG_HALF_HEIGHT), "body_origin": (0, 0, 0)}, fixture=True, symmetry="z4",
                  mass=0.0, color=(0.55, 0.35, 0.2, 1.0))


@lru_cache(maxsize=None)
def round_peg(obj_id: str = "round_peg") -> ObjectSpec:
    parts = (cylinder(ROUND_PEG_RADIUS, PEG_HALF_HEIGHT),)
    return _build(obj_id, "round_peg", parts, {"top": (0, 0, PEG_HALF_HEIGHT), "body_origin": (0, 0, 0)}, fixture=True,
                  symmetry="z_continuous", mass=0.0, color=(0.35, 0.35, 0.4, 1.0))


@lru_cache(maxsize=None)
def milk(obj_id: str = "milk") -> ObjectSpec:
    """Milk-carton-like box: 5 x 5 x 11 cm, grasped across its 5 cm width."""
    parts = (box(0.025, 0.025, 0.055),)
    return _build(obj_id, "milk", parts, {"top": (0, 0, 0.055)}, fixture=False, symmetry="z4", mass=0.1,
                  color=(0.9, 0.9, 0.95, 1.0))


@lru_cache(maxsize=None)
def bin_(obj_id: str = "bin") -> ObjectSpec:
    a, w, hw = BIN_INNER_HALF, 0.01, BIN_WALL_HEIGHT
    parts = (box(a + w, a + w, 0.005, z=0.005),
             box(w / 2, a + w, hw / 2, x=a + w / 2, z=hw / 2), box(w / 2, a + w, hw / 2, x=-(a + w / 2), z=hw / 2),
             box(a, w / 2, hw / 2, y=a + w / 2, z=hw / 2), box(a, w / 2, hw / 2, y=-(a + w / 2), z=hw / 2))
    return _build(obj_id, "bin", parts, {"floor_center": (0, 0, 0.01)}, fixture=True, symmetry="z4", mass=0.0,
                  color=(0.45, 0.3, 0.15, 1.0))


@lru_cache(maxsize=None)
def needle(obj_id: str = "needle") -> ObjectSpec:
    """MimicGen's NeedleObject: a 4 cm cube handle with a 1 x 1 x 12 cm shaft along +x; grasped at the handle."""
    h, s, L = NEEDLE_HANDLE_HALF, NEEDLE_SHAFT_HALF, NEEDLE_SHAFT_HALF_LEN
    parts = (box(h, h, h), box(L, s, s, x=h + L))
    kp = {"handle": (0, 0, 0), "shaft_base": (h, 0, 0), "shaft_center": (h + L, 0, 0), "tip": (h + 2 * L, 0, 0),
          "body_origin": ((2 * h + 2 * L) / 2 - h, 0, 0)}  # MimicGen's body origin: the 16 cm box's centre
    mass = MIMICGEN_DENSITY * sum(8 * float(np.prod(p.size)) for p in parts)   # 7.6 g
    return _build(obj_id, "needle", parts, kp, fixture=False, symmetry="none", mass=mass,
                  color=(0.8, 0.15, 0.15, 1.0))


def _tripod_legs() -> list[Part]:
    """ring_tripod.py's three capsule legs (r 0.01, half 0.03 + cap), each leaning 30 deg toward the post."""
    legs = []
    for x, y in ((-0.04, -0.04), (-0.04, 0.04), (0.04, 0.0)):
        to_centre = -np.array([x, y, 0.0]) / np.hypot(x, y)
        tilt = Rotation.from_rotvec(np.radians(30.0) * np.cross([0.0, 0.0, 1.0], to_centre) * -1.0)
        if tilt.apply([0.0, 0.0, 1.0]) @ to_centre < 0:   # lean the top toward the post
            tilt = tilt.inv()
        legs.append(Part("cylinder", (0.01, 0.04, 0.0), (x, y, -0.06), tuple(tilt.as_quat())))
    return legs


@lru_cache(maxsize=None)
def tripod(obj_id: str = "tripod") -> ObjectSpec:
    """MimicGen's RingTripodObject: a 1.6 cm square ring (opening axis = object x) 18.8 cm above the table."""
    ux, o, b = RING_UNIT[0], RING_OPENING_HALF, 2 * RING_UNIT[1]   # ring: 1 cm along x, 4 mm bars
    zc, post_half = RING_CENTER_Z, 0.043   # post: total_size z - ring_size z - plate - capsule r - h
    parts = [box(ux, o + b, b / 2, z=zc + o + b / 2), box(ux, o + b, b / 2, z=zc - o - b / 2),
             box(ux, b / 2, o, y=o + b / 2, z=zc), box(ux, b / 2, o, y=-(o + b / 2), z=zc),
             box(0.005, 0.005, post_half, z=-0.01 + post_half),
             box(TRIPOD_HALF[0], TRIPOD_HALF[1], 0.005, z=-0.015)] + _tripod_legs()
    kp = {"ring_center": (0, 0, zc), "body_origin": (0, 0, 0)}
    return _build(obj_id, "tripod", tuple(parts), kp, fixture=True, symmetry="none",
                  mass=0.0, color=(0.2, 0.6, 0.25, 1.0), friction=RING_FRICTION)


@lru_cache(maxsize=None)
def obstacle(obj_id: str = "obstacle") -> ObjectSpec:
    """The clutter variants' large obstruction: a 10 x 10 x 16 cm block."""
    return _build(obj_id, "obstacle", (box(0.05, 0.05, 0.08),), {"top": (0, 0, 0.08)}, fixture=True,
                  symmetry="z4", mass=0.0, color=(0.3, 0.3, 0.7, 1.0))

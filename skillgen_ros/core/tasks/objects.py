"""The task objects: nuts with handles, pegs, milk carton, bin, needle, tripod, obstacle.

Sizes follow the issue (square peg 3.2 cm / nut hole 4.6 cm; round peg 4 cm / hole 6.8 cm;
needle through a tripod ring with about 1 cm clearance). Each builder returns an ObjectSpec whose
OBJ mesh (core/tasks/meshes/<type>.obj) is written from the same primitives the simulator uses.
Keypoints name the features scripted solvers and success predicates need (in the object frame).
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from .shapes import Part, aabb, box, cylinder, recentre, write_obj
from .spec import ObjectSpec

MESH_DIR = Path(__file__).resolve().parent / "meshes"

NUT_WALL = 0.012
NUT_HALF_THICK = 0.01
NUT_HANDLE_LEN = 0.055
NUT_HANDLE_HALF_WIDTH = 0.01
PEG_HALF_HEIGHT = 0.05
SQUARE_PEG_HALF = 0.016      # 3.2 cm
SQUARE_HOLE_HALF = 0.023     # 4.6 cm
ROUND_PEG_RADIUS = 0.02      # 4 cm
ROUND_HOLE_RADIUS = 0.034    # 6.8 cm
NEEDLE_SHAFT_HALF = 0.004    # 8 mm square shaft
RING_OPENING_HALF = 0.014    # 2.8 cm opening: 1 cm clearance around the shaft
RING_HEIGHT = 0.10           # ring centre above the table
BIN_INNER_HALF = 0.09
BIN_WALL_HEIGHT = 0.06


def _build(obj_id: str, type_: str, parts: tuple[Part, ...], keypoints: dict, *, fixture: bool,
           symmetry: str, mass: float, color, friction: float = 1.0) -> ObjectSpec:
    parts, shift = recentre(parts)
    lo, hi = aabb(parts)
    kps = tuple((k, tuple(float(x) for x in np.asarray(v) + shift)) for k, v in keypoints.items())
    path = MESH_DIR / f"{type_}.obj"
    write_obj(parts, path, type_)
    return ObjectSpec(id=obj_id, type=type_, mesh_path=str(path), half_extents=tuple(float(x) for x in (hi - lo) / 2),
                      is_fixture=fixture, symmetry=symmetry, mass=0.0 if fixture else mass, parts=parts,
                      color=tuple(color), friction=friction, keypoints=kps)


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
    kp = {"ring_center": (0, 0, 0), "handle": (h + w + NUT_HANDLE_LEN / 2, 0, 0)}
    return _build(obj_id, "square_nut", parts, kp, fixture=False, symmetry="none", mass=0.05,
                  color=(0.75, 0.55, 0.2, 1.0))


@lru_cache(maxsize=None)
def round_nut(obj_id: str = "round_nut") -> ObjectSpec:
    n, r, w, t = 12, ROUND_HOLE_RADIUS, NUT_WALL, NUT_HALF_THICK  # pybullet visual arrays crash above 16 parts
    half_len = (r + w) * np.tan(np.pi / n)
    parts = tuple(box(w / 2, half_len, t, x=(r + w / 2) * np.cos(a), y=(r + w / 2) * np.sin(a), yaw=a)
                  for a in np.arange(n) * 2 * np.pi / n) + (_nut_handle(r + w),)
    kp = {"ring_center": (0, 0, 0), "handle": (r + w + NUT_HANDLE_LEN / 2, 0, 0)}
    return _build(obj_id, "round_nut", parts, kp, fixture=False, symmetry="none", mass=0.05,
                  color=(0.5, 0.5, 0.55, 1.0))


@lru_cache(maxsize=None)
def square_peg(obj_id: str = "square_peg") -> ObjectSpec:
    parts = (box(SQUARE_PEG_HALF, SQUARE_PEG_HALF, PEG_HALF_HEIGHT),)
    return _build(obj_id, "square_peg", parts, {"top": (0, 0, PEG_HALF_HEIGHT)}, fixture=True, symmetry="z4",
                  mass=0.0, color=(0.55, 0.35, 0.2, 1.0))


@lru_cache(maxsize=None)
def round_peg(obj_id: str = "round_peg") -> ObjectSpec:
    parts = (cylinder(ROUND_PEG_RADIUS, PEG_HALF_HEIGHT),)
    return _build(obj_id, "round_peg", parts, {"top": (0, 0, PEG_HALF_HEIGHT)}, fixture=True,
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
    """A 6 cm handle block with a 10 cm thin square shaft along +x; grasped at the handle."""
    s = NEEDLE_SHAFT_HALF
    parts = (box(0.03, 0.01, 0.01), box(0.05, s, s, x=0.08))
    kp = {"handle": (0, 0, 0), "shaft_base": (0.03, 0, 0), "tip": (0.13, 0, 0)}
    return _build(obj_id, "needle", parts, kp, fixture=False, symmetry="none", mass=0.03,
                  color=(0.8, 0.15, 0.15, 1.0))


@lru_cache(maxsize=None)
def tripod(obj_id: str = "tripod") -> ObjectSpec:
    """A square ring (opening axis = object x) on a post with three feet; the ring is at 10 cm."""
    o, b, d, H = RING_OPENING_HALF, 0.008, 0.005, RING_HEIGHT
    post_half = (H - o - b) / 2
    parts = [box(d, o + b, b / 2, z=o + b / 2), box(d, o + b, b / 2, z=-(o + b / 2)),
             box(d, b / 2, o, y=o + b / 2), box(d, b / 2, o, y=-(o + b / 2)),
             box(0.006, 0.006, post_half, z=-(o + b) - post_half)]
    for a in np.radians([90.0, 210.0, 330.0]):
        parts.append(box(0.03, 0.006, 0.005, x=0.03 * np.cos(a), y=0.03 * np.sin(a), z=-H + 0.005, yaw=a))
    return _build(obj_id, "tripod", tuple(parts), {"ring_center": (0, 0, 0)}, fixture=True, symmetry="none",
                  mass=0.0, color=(0.2, 0.6, 0.25, 1.0))


@lru_cache(maxsize=None)
def obstacle(obj_id: str = "obstacle") -> ObjectSpec:
    """The clutter variants' large obstruction: a 10 x 10 x 16 cm block."""
    return _build(obj_id, "obstacle", (box(0.05, 0.05, 0.08),), {"top": (0, 0, 0.08)}, fixture=True,
                  symmetry="z4", mass=0.0, color=(0.3, 0.3, 0.7, 1.0))

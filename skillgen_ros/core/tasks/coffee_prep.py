"""Coffee Prep's objects and success rule: MimicGen's CoffeePreparation (a mug, a drawer cabinet holding the
pod, and Coffee's machine with its lid closed).

References (NVlabs/mimicgen):
- `mimicgen/envs/robosuite/coffee.py` (CoffeePreparation: `_get_mug_model`, `_load_model` (LongDrawerObject
  "CabinetObject", CoffeeMachineObject(add_cup=False)), `_get_initial_placement_bounds` and
  `_get_placement_initializer` (the pod's CoffeePodInDrawerSampler), `_reset_internal` (the drawer a fixture at
  z 0.805, the hinge and the drawer slide closed, the pod on the drawer bottom), `_check_mug_placement`,
  `_get_partial_task_metrics`: success = Coffee's lid and pod checks and the mug placement);
- `mimicgen/models/robosuite/assets/objects/drawer_long.xml` (the cabinet's geoms, the drawer link, its slide);
- `mimicgen/models/robosuite/assets/shapenet_core/mugs/3143a4ac/` (the mug: model.xml's sites, the meshes at
  scale 0.15), `mimicgen/models/robosuite/objects/xml_objects.py` (LongDrawerObject, BlenderObject);
- `mimicgen/env_interfaces/robosuite.py` MG_CoffeePreparation (the subtasks' ends: drawer_open at slide < -0.19).

The drawer's frame is drawer_long.xml's "base" body (MimicGen's root body, where the placement puts it); the
mug's is model.xml's "object" body. Both keep those as their "body_origin" keypoint, which the regions hold.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import InvalidInputError
from . import coffee as C
from .articulation import Joint, Link
from .objects import _build
from .shapes import Part, box
from .spec import ObjectSpec, SceneState

# ---- the cabinet: drawer_long.xml, "base" body geoms (pos, size), frame = the base body
CABINET_GEOMS = (
    ((-0.11, -0.0315, 0.065), (0.008, 0.1435, 0.064)),    # drawer_left_wall
    ((0.11, -0.0315, 0.065), (0.008, 0.1435, 0.064)),     # drawer_right_wall
    ((0.0, 0.092, 0.062), (0.102, 0.008, 0.064)),         # drawer_back_wall
    ((0.0, -0.0395, 0.004), (0.102, 0.1335, 0.014)),      # drawer_bottom_surface
    ((0.0, -0.0215, 0.121), (0.102, 0.1335, 0.008)),      # drawer_top_surface
    ((-0.102, -0.163, 0.065), (0.012, 0.012, 0.064)),     # drawer_cavity_1
    ((0.102, -0.163, 0.065), (0.012, 0.012, 0.064)),      # drawer_cavity_2
)
# drawer_long.xml "drawer_link" body at pos (0, -0.01, 0.076) in the base; its box geoms (pos, size)
DRAWER_LINK_POS = (0.0, -0.01, 0.076)
DRAWER_GEOMS = (
    ((0.0, -0.155, 0.007), (0.088, 0.010, 0.046)),        # drawer_tray_1 (the front)
    ((0.0, 0.065, 0.008), (0.095, 0.008, 0.028)),         # drawer_tray_2 (the back)
    ((-0.072, -0.042, -0.015), (0.008, 0.114, 0.008)),    # drawer_tray_3
    ((0.072, -0.042, -0.015), (0.008, 0.114, 0.008)),     # drawer_tray_4
)
DRAWER_BOTTOM_POS, DRAWER_BOTTOM_HALF = (0.0, -0.04, -0.03), (0.08, 0.12, 0.008)   # drawer_bottom
# drawer_handle_1..3: capsules radius 0.009, half lengths 0.03 (along y at x -+0.05, y -0.19) and 0.05 (along x
# at y -0.22), all at z 0.04. Ours: cylinders over each capsule's full length (caps included).
HANDLE_R, HANDLE_Z = 0.009, 0.04
HANDLE_POSTS = ((-0.05, -0.19), (0.05, -0.19))
HANDLE_POST_HALF, HANDLE_BAR_Y, HANDLE_BAR_HALF = 0.03, -0.22, 0.05
# the slide "goal_slidey": axis (0, 1, 0), range -1.0 .. 0 (the drawer opens toward -y), damping 100; the reset
# sets 0 (closed). drawer_link's inertial mass 7.85398 kg (drawer_long.xml, kept from BUDS); ours puts its
# centre of mass at the parts' centroid (the xml's is 0.35 m above the link, a BUDS leftover).
SLIDE_LOWER, SLIDE_UPPER, SLIDE_DAMPING, DRAWER_MASS = -1.0, 0.0, 100.0, 7.85398
# MG_CoffeePreparation.get_subtask_term_signals: "drawer_open" when the slide is below -0.19
DRAWER_OPEN = -0.19
# coffee.py CoffeePreparation._reset_internal: the cabinet body at z 0.805 on the 0.8 table, 5 mm up, which sinks
# drawer_bottom_surface (base z -0.010 .. 0.018) 5 mm into the table. Ours rests it on the table: 5 mm higher.
CABINET_SINK = 0.005

# ---- the pod in the drawer: _get_placement_initializer's CoffeePodInDrawerSampler, x (-0.03, 0.03),
# y (-0.05, 0.03) from the centre of the drawer_bottom geom, in the drawer's frame, z_rot 0; _reset_internal
# puts the pod's bottom 1 mm over that geom's top.
POD_IN_DRAWER_X, POD_IN_DRAWER_Y, POD_DROP = (-0.03, 0.03), (-0.05, 0.03), 0.001

# ---- the mug: shapenet_core/mugs/3143a4ac (BlenderObject scale 1.0; model.xml meshes at scale 0.15), model frame.
# model.xml sites: bottom_site z -0.03864, top_site z 0.04183; the collision hulls' bounds: x +-0.0353,
# y -0.05785 .. 0.04409 (the handle on +y). The visual mesh: a round body about the axis at y -0.02255 (the
# collision bounds' y min + 0.0353), inner wall radius 0.0305, the interior floor at z -0.0314; the handle a
# 1.28 cm wide loop (x +-0.0064), arms at z -0.030 .. -0.022 and 0.030 .. 0.037 joined by a post at the outside.
MUG_BOTTOM, MUG_TOP = -0.03864, 0.04183
MUG_R_OUT, MUG_R_IN, MUG_AXIS_Y = 0.0353, 0.0305, -0.02255
MUG_FLOOR_TOP = -0.0314
MUG_HANDLE_HALF_X, MUG_HANDLE_Y_OUT = 0.0064, 0.04409
MUG_HANDLE_ARMS = ((-0.030, -0.022), (0.030, 0.037))
MUG_HANDLE_POST_Y = 0.0376
MUG_NGEOMS = 12       # ours: the wall as 12 boxes (hollow_cylinder.py's ring), the floor a disk: 16 parts in all
MUG_DENSITY = 100.0   # coffee.py _get_mug_model: BlenderObject(density=100)
# ours: the demonstrator's fingers close across the mug's body (its 7.06 cm < the hand's 8 cm), the grasp point on
# its axis this far under the rim
MUG_GRASP_BELOW_TOP = 0.012
# coffee.py CoffeePreparation._check_mug_placement: upright when 1 - (the mug's z axis . world z) < 1e-3 (2.6 deg),
# and touching the base plate geom (coffee_machine_base_g0). A SceneState has no contacts: ours is the mug's
# bottom within MUG_CONTACT_GAP above the plate's top (the mug's margin, 0.001 in _get_mug_model: MuJoCo reports
# contacts that near) or up to MUG_CONTACT_DEPTH into it (ours: pybullet's penetration), with the bottom disk
# overlapping the plate in x-y.
MUG_UPRIGHT_TOLERANCE = 1e-3
MUG_CONTACT_GAP, MUG_CONTACT_DEPTH = 0.001, 0.005


def _cylinder_along(axis: str, r: float, half_len: float, pos) -> Part:
    """A cylinder part whose axis is the object's x or y (a drawer_long.xml capsule)."""
    rot = Rotation.from_euler("y" if axis == "x" else "x", np.pi / 2)
    return Part("cylinder", (r, half_len, 0.0), tuple(float(v) for v in pos), tuple(rot.as_quat()))


def _drawer_link_parts() -> tuple[Part, ...]:
    parts = tuple(box(*half, *pos) for pos, half in DRAWER_GEOMS) + (box(*DRAWER_BOTTOM_HALF, *DRAWER_BOTTOM_POS),)
    posts = tuple(_cylinder_along("y", HANDLE_R, HANDLE_POST_HALF + HANDLE_R, (x, y, HANDLE_Z)) for x, y in HANDLE_POSTS)
    bar = _cylinder_along("x", HANDLE_R, HANDLE_BAR_HALF + HANDLE_R, (0.0, HANDLE_BAR_Y, HANDLE_Z))
    return parts + posts + (bar,)


@lru_cache(maxsize=None)
def drawer(obj_id: str = "drawer") -> ObjectSpec:
    """MimicGen's LongDrawerObject: the cabinet fixed, the drawer (tray and handle) a link on the slide."""
    parts = tuple(box(*half, *pos) for pos, half in CABINET_GEOMS)
    tray_top = (DRAWER_BOTTOM_POS[0], DRAWER_BOTTOM_POS[1], DRAWER_BOTTOM_POS[2] + DRAWER_BOTTOM_HALF[2])
    handle = (0.0, HANDLE_BAR_Y - HANDLE_R, HANDLE_Z)   # the bar's front
    tray = Link("tray", _drawer_link_parts(), mass=DRAWER_MASS, color=(0.55, 0.22, 0.15, 1.0),
                keypoints=(("handle", handle), ("tray_top", tray_top)))
    slide = Joint("slide", "prismatic", "tray", DRAWER_LINK_POS, (0.0, 1.0, 0.0), SLIDE_LOWER, SLIDE_UPPER, 0.0,
                  damping=SLIDE_DAMPING)
    at_closed = lambda p: tuple(float(a + b) for a, b in zip(DRAWER_LINK_POS, p))   # noqa: E731 -- link -> base
    kp = {"body_origin": (0.0, 0.0, 0.0), "handle": at_closed(handle), "tray_top": at_closed(tray_top)}
    return _build(obj_id, "drawer", parts, kp, fixture=True, symmetry="none", mass=0.0,
                  color=(0.55, 0.22, 0.15, 1.0), links=(tray,), joints=(slide,))


def _mug_parts() -> tuple[Part, ...]:
    """hollow_cylinder.py's ring (as coffee.py's holder) from MUG_R_IN to MUG_R_OUT over the full height, a floor
    disk up to MUG_FLOOR_TOP, and the handle as two arms and a post."""
    n, r1, r2, cy = MUG_NGEOMS, MUG_R_IN, MUG_R_OUT, MUG_AXIS_Y
    w, h = r2 * np.sin(np.pi / n), (r2 - r1) * np.cos(np.pi / n) / 2.0
    int_r = r1 * np.cos(np.pi / n) + h
    hz, cz = (MUG_TOP - MUG_BOTTOM) / 2, (MUG_TOP + MUG_BOTTOM) / 2
    ring = tuple(box(h, w, hz, x=int_r * np.cos(a), y=cy + int_r * np.sin(a), z=cz, yaw=a)
                 for a in np.arange(n) * 2 * np.pi / n)
    fz = (MUG_FLOOR_TOP - MUG_BOTTOM) / 2
    floor = Part("cylinder", (int_r, fz, 0.0), (0.0, cy, MUG_BOTTOM + fz))
    y0 = cy + int_r   # the arms start inside the wall
    arms = tuple(box(MUG_HANDLE_HALF_X, (MUG_HANDLE_Y_OUT - y0) / 2, (z1 - z0) / 2,
                     y=(MUG_HANDLE_Y_OUT + y0) / 2, z=(z0 + z1) / 2) for z0, z1 in MUG_HANDLE_ARMS)
    (_, lo), (hi, _) = MUG_HANDLE_ARMS
    post = box(MUG_HANDLE_HALF_X, (MUG_HANDLE_Y_OUT - MUG_HANDLE_POST_Y) / 2, (hi - lo) / 2,
               y=(MUG_HANDLE_Y_OUT + MUG_HANDLE_POST_Y) / 2, z=(lo + hi) / 2)
    return ring + (floor,) + arms + (post,)


def _volume(parts: tuple[Part, ...]) -> float:
    return float(sum(8 * np.prod(p.size) if p.kind == "box" else np.pi * p.size[0] ** 2 * 2 * p.size[1] for p in parts))


@lru_cache(maxsize=None)
def mug(obj_id: str = "mug") -> ObjectSpec:
    """The ShapeNet mug 3143a4ac: 7.06 cm across, 8.05 cm tall, its handle on its +y; density 100 (11 g)."""
    parts = _mug_parts()
    kp = {"body_origin": (0.0, 0.0, 0.0), "axis_bottom": (0.0, MUG_AXIS_Y, MUG_BOTTOM),
          "top": (0.0, MUG_AXIS_Y, MUG_TOP), "grasp": (0.0, MUG_AXIS_Y, MUG_TOP - MUG_GRASP_BELOW_TOP)}
    return _build(obj_id, "mug", parts, kp, fixture=False, symmetry="none", mass=MUG_DENSITY * _volume(parts),
                  color=(0.82, 0.71, 0.55, 1.0))


@lru_cache(maxsize=None)
def machine(obj_id: str = "coffee_machine") -> ObjectSpec:
    """Coffee's machine (CoffeeMachineObject(add_cup=False): Coffee's is built without the cup too), lid closed
    at reset (CoffeePreparation._reset_internal: hinge 0); its own type, so its mesh shows the lid closed."""
    return C.coffee_machine(obj_id, 0.0, "coffee_machine_closed")


def pod_on_tray_z(cabinet: ObjectSpec, table_z: float) -> float:
    """World z of the pod's origin in the closed drawer of a cabinet resting on the table (_reset_internal:
    the drawer_bottom geom's top + the pod's bottom offset + 1 mm)."""
    return float(table_z + cabinet.half_extents[2] + cabinet.keypoint("tray_top")[2] + C.POD_HALF[2] + POD_DROP)


def pod_in_drawer_xy(cabinet_xy, cabinet_yaw: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """The pod sampler's box in the world for a cabinet whose body origin is at `cabinet_xy` with yaw `cabinet_yaw`
    (a fixed cabinet: a multiple of pi / 2, so the box stays axis-aligned)."""
    k = cabinet_yaw / (np.pi / 2)
    if abs(k - round(k)) > 1e-9:
        raise InvalidInputError("the pod's world box needs the cabinet's yaw a multiple of 90 deg")
    R = Rotation.from_euler("z", cabinet_yaw)
    base = np.asarray(drawer().keypoint("tray_top")) - np.asarray(drawer().keypoint("body_origin"))  # from the body
    corners = np.array([R.apply([base[0] + x, base[1] + y, 0.0])[:2] for x in POD_IN_DRAWER_X for y in POD_IN_DRAWER_Y])
    lo, hi = corners.min(axis=0) + np.asarray(cabinet_xy), corners.max(axis=0) + np.asarray(cabinet_xy)
    return (round(float(lo[0]), 6), round(float(hi[0]), 6)), (round(float(lo[1]), 6), round(float(hi[1]), 6))


def mug_upright(mug_spec: ObjectSpec, state: SceneState) -> bool:
    """_check_mug_placement: 1 - (the mug's z axis . world z) < 1e-3."""
    return bool(1.0 - state.poses[mug_spec.id].rotation.apply([0.0, 0.0, 1.0])[2] < MUG_UPRIGHT_TOLERANCE)


def mug_on_base(machine_spec: ObjectSpec, mug_spec: ObjectSpec, state: SceneState) -> bool:
    """Ours for _check_mug_placement's contact with the base plate: the mug's bottom centre within
    MUG_CONTACT_GAP above / MUG_CONTACT_DEPTH below the plate's top, its bottom disk over the plate in x-y."""
    m, g = state.poses[machine_spec.id], state.poses[mug_spec.id]
    bottom = g.rotation.apply(mug_spec.keypoint("axis_bottom")) + g.position
    top = m.rotation.apply(machine_spec.keypoint("base_top")) + m.position
    if not -MUG_CONTACT_DEPTH <= bottom[2] - top[2] <= MUG_CONTACT_GAP:
        return False
    local = m.rotation.inv().apply(bottom - top)[:2]   # in the plate's frame (the machine's, unrotated parts)
    outside = np.maximum(np.abs(local) - np.asarray(C.BASE_HALF[:2]), 0.0)
    return bool(np.linalg.norm(outside) < MUG_R_OUT)


def mug_placed(machine_spec: ObjectSpec, mug_spec: ObjectSpec, state: SceneState) -> bool:
    """coffee.py CoffeePreparation._check_mug_placement: upright and on the machine's base plate."""
    return mug_upright(mug_spec, state) and mug_on_base(machine_spec, mug_spec, state)


def coffee_preparation_success(machine_spec: ObjectSpec, pod: ObjectSpec, mug_spec: ObjectSpec,
                               state: SceneState) -> bool:
    """CoffeePreparation._get_partial_task_metrics()["task"]: Coffee's lid and pod checks and the mug placement."""
    return C.coffee_success(machine_spec, pod, state) and mug_placed(machine_spec, mug_spec, state)

"""Coffee's objects and success rule: MimicGen's coffee machine (hinged lid over a pod holder) and pod.

References (NVlabs/mimicgen):
- `mimicgen/models/robosuite/objects/composite_body/coffee_machine.py` (CoffeeMachineObject.__init__: where
  body, lid, base, pod_holder_holder and pod_holder go, the lid hinge), `.../composite_body/cup.py` (CupObject:
  the pod holder), `.../composite/hollow_cylinder.py` (HollowCylinderObject: the holder's wall of boxes);
- `mimicgen/models/robosuite/assets/objects/coffee_{body,lid,base,pod}.xml`: bounding boxes from each model's
  `horizontal_radius_site` and `bottom_site` (robosuite 1.5.2 MujocoXMLObject.get_bounding_box_half_size),
  which match the STL meshes' bounds (scale 0.01; the pod 0.018);
- `mimicgen/envs/robosuite/coffee.py` (Coffee: `_reset_internal` sets the hinge to 2 pi / 3, `_check_lid`,
  `_check_pod`, `_get_partial_task_metrics`: success = lid check and pod check).

Our machine frame is MimicGen's root body frame: CoffeeMachineObject places its parts relative to the
corner of `total_size` = (body x, body y + base y, body z), whose centre is the root body and, for the
fixed parts, the centre of their bounding box. The body mesh is an elliptic column (0.173 x 0.201 m,
22.1 cm tall): we build it from three boxes spanning its extents. The holder is MimicGen's 64-box ring
(hollow_cylinder.py) with its cup base. The lid is its bounding box on the hinge. The machine is a fixture
(MimicGen gives it a free joint, but it is heavy and the task never moves it).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .articulation import Joint, Link, joint_key, joint_values, link_point
from .objects import _build
from .shapes import Part, box, cylinder
from .spec import ObjectSpec, SceneState

# bounding-box half sizes: horizontal_radius_site - bottom_site of each xml
BODY_HALF = (0.0865, 0.1005, 0.1105)     # coffee_body.xml
LID_HALF = (0.0295, 0.044, 0.0095)       # coffee_lid.xml
BASE_HALF = (0.042, 0.05, 0.005)         # coffee_base.xml
POD_HALF = (0.0243, 0.0243, 0.023103)    # coffee_pod.xml (the success rule's pod_size)
# coffee_machine.py pod_holder: CupObject(outer_cup_radius=lid_size[0], inner_cup_radius=0.025, cup_height=0.028,
# cup_ngeoms=64, cup_base_height=0.005, cup_base_offset=0.002); its bounding box (r2, r2, cup_height) is pod_holder_size
HOLDER_R_OUT, HOLDER_R_IN, HOLDER_HALF_H, HOLDER_NGEOMS = LID_HALF[0], 0.025, 0.028, 64
HOLDER_BASE_HALF_H, HOLDER_BASE_OFFSET = 0.005, 0.002
HOLDER_HALF = (HOLDER_R_OUT, HOLDER_R_OUT, HOLDER_HALF_H)
# pod_holder_holder: BoxObject size [0.01, 0.9 * (lid_size[1] - lid_size[0]), 0.005]
BRACKET_HALF = (0.01, 0.9 * (LID_HALF[1] - LID_HALF[0]), 0.005)
TOTAL_HALF = (BODY_HALF[0], BODY_HALF[1] + BASE_HALF[1], BODY_HALF[2])   # total_size


def _corner(loc, half) -> np.ndarray:
    """CompositeBodyObject locations_relative_to_corner: pos = -total_size + half_size + location."""
    return -np.asarray(TOTAL_HALF) + np.asarray(half) + np.asarray(loc)


# coffee_machine.py object_locations (body at 0 turned 180 deg about z; the others unrotated)
BODY_POS = _corner((0.0, 0.0, 0.0), BODY_HALF)
LID_POS = _corner((BODY_HALF[0] - LID_HALF[0], 2 * BODY_HALF[1] + 0.01, 2 * (BODY_HALF[2] - LID_HALF[2]) + 0.005),
                  LID_HALF)
BASE_POS = _corner((BODY_HALF[0] - BASE_HALF[0], 2 * BODY_HALF[1], 0.0), BASE_HALF)
BRACKET_POS = _corner((BODY_HALF[0] - BRACKET_HALF[0], 2 * BODY_HALF[1],
                       2 * (BODY_HALF[2] - LID_HALF[2] - BRACKET_HALF[2])), BRACKET_HALF)
HOLDER_POS = _corner((BODY_HALF[0] - HOLDER_HALF[0], 2 * (BODY_HALF[1] + BRACKET_HALF[1]),
                      2 * (BODY_HALF[2] - LID_HALF[2] - HOLDER_HALF[2])), HOLDER_HALF)
# the hinge: axis "1 0 0" at pos (0, -lid_size[1], 0) in the lid body, range 0 .. 2 pi / 3, damping 0.005
HINGE_POS = LID_POS + np.array([0.0, -LID_HALF[1], 0.0])
LID_UPPER = 2.0 * np.pi / 3.0
LID_OPEN = 2.0 * np.pi / 3.0        # coffee.py Coffee._reset_internal: qpos[hinge] = 2 pi / 3
LID_DAMPING = 0.005
# Ours: Coulomb friction (N m) of the hinge, under the 0.1 kg lid's gravity torque at horizontal (0.043 N m), so
# the lid rests where it is left within ~28 deg of upright and falls shut from lower, as MimicGen's does.
LID_FRICTION = 0.02
DENSITY = 1000.0                    # coffee_*.xml geoms: density 1000 (the lid); the pod: 100
# coffee.py Coffee._check_lid: hinge angle < 15 deg
LID_CLOSED_TOLERANCE = np.radians(15.0)
# the pod (coffee_pod.stl's convex hull, scale 0.018): a frustum from r 0.0205 at the bottom to r 0.0228 at
# z 0.0201, a rim r 0.0243 up to the top: a cylinder of the mean radius plus the rim
POD_BODY_R, POD_RIM_Z = 0.0217, 0.0201
POD_GRASP_BELOW_TOP = 0.008   # ours: where the demonstrator's fingers close, on the pod's upper body
# MimicGen's density 100 makes the pod 7 g. pybullet's contact solver lets the 20 N fingers squeeze through so light
# an object: measured, a 7 g pod (a 7 g box too) is pushed out of the grasp by a 0.8 rad joint-1 turn in 1.5 s,
# while from 25 g up the fingers stay on the rim and it tilts < 6 deg; ours weighs 50 g (a pybullet constraint,
# not the reference's value).
POD_MASS = 0.05


def _holder_parts(centre: np.ndarray) -> tuple[Part, ...]:
    """hollow_cylinder.py's ring of 64 boxes (unit_box_width = r2 sin(pi/n), unit_box_height = (r2 - r1)
    cos(pi/n) / 2, centres at int_r = r1 cos(pi/n) + unit_box_height) and cup.py's base disk (radius int_r,
    half height 0.005 at z = -cup_height + cup_base_height + cup_base_offset)."""
    n, r1, r2 = HOLDER_NGEOMS, HOLDER_R_IN, HOLDER_R_OUT
    w, h = r2 * np.sin(np.pi / n), (r2 - r1) * np.cos(np.pi / n) / 2.0
    int_r = r1 * np.cos(np.pi / n) + h
    ring = tuple(box(h, w, HOLDER_HALF_H, x=centre[0] + int_r * np.cos(a), y=centre[1] + int_r * np.sin(a),
                     z=centre[2], yaw=a) for a in np.pi - np.arange(n) * 2 * np.pi / n)
    z_base = -HOLDER_HALF_H + HOLDER_BASE_HALF_H + HOLDER_BASE_OFFSET
    return ring + (cylinder(int_r, HOLDER_BASE_HALF_H, x=centre[0], y=centre[1], z=centre[2] + z_base),)


def _body_parts() -> tuple[Part, ...]:
    """The elliptic column (semi-axes 0.0865 x 0.1005) as three full-height boxes: its x extent, its
    45 deg inscribed rectangle, its y extent (the ends' corners stand out of the ellipse by <= 5 mm)."""
    a, b, hz = BODY_HALF
    c = BODY_POS
    return tuple(box(hx, hy, hz, x=c[0], y=c[1], z=c[2]) for hx, hy in
                 ((a, b * np.sin(np.radians(20))), (a * np.cos(np.radians(45)), b * np.sin(np.radians(45))),
                  (a * np.cos(np.radians(70)), b)))


@lru_cache(maxsize=None)
def coffee_machine(obj_id: str = "coffee_machine", lid_initial: float = LID_OPEN,
                   type_: str = "coffee_machine") -> ObjectSpec:
    """The machine: body, drip base, holder bracket and pod holder fixed; the lid on the hinge.

    `lid_initial`: the hinge value a reset sets (Coffee: open, 2 pi / 3; CoffeePreparation: closed, 0). The
    mesh shows the lid there, so a machine reset otherwise needs its own `type_` (its own mesh file)."""
    parts = _body_parts() + (box(*BASE_HALF, *BASE_POS), box(*BRACKET_HALF, *BRACKET_POS)) + _holder_parts(HOLDER_POS)
    lid_local = (0.0, LID_HALF[1], 0.0)   # the lid body's origin from the hinge
    lid_parts = (box(*LID_HALF, *lid_local),)
    lid = Link("lid", lid_parts, mass=DENSITY * 8 * float(np.prod(LID_HALF)), color=(0.84, 0.84, 0.84, 1.0),
               keypoints=(("body_origin", lid_local), ("handle", (0.0, 2 * LID_HALF[1], 0.0))))
    hinge = Joint("lid", "revolute", "lid", tuple(float(x) for x in HINGE_POS), (1.0, 0.0, 0.0), 0.0, LID_UPPER,
                  float(lid_initial), damping=LID_DAMPING, friction=LID_FRICTION)
    kp = {"body_origin": (0, 0, 0), "pod_holder": tuple(HOLDER_POS),
          "holder_top": tuple(HOLDER_POS + np.array([0.0, 0.0, HOLDER_HALF_H])),
          "base_top": tuple(BASE_POS + np.array([0.0, 0.0, BASE_HALF[2]]))}   # the drip base's top: a mug stands there
    return _build(obj_id, type_, parts, kp, fixture=True, symmetry="none", mass=0.0,
                  color=(0.13, 0.13, 0.13, 1.0), links=(lid,), joints=(hinge,))


@lru_cache(maxsize=None)
def coffee_pod(obj_id: str = "coffee_pod") -> ObjectSpec:
    """The pod: 4.6 cm tall, 4.86 cm across its rim; 50 g (POD_MASS: MimicGen's density 100 gives 7 g)."""
    hz = POD_HALF[2]
    body_half = (POD_RIM_Z + hz) / 2
    rim_half = (hz - POD_RIM_Z) / 2
    parts = (cylinder(POD_BODY_R, body_half, z=-hz + body_half), cylinder(POD_HALF[0], rim_half, z=hz - rim_half))
    kp = {"body_origin": (0, 0, 0), "top": (0, 0, hz), "bottom": (0, 0, -hz), "grasp": (0, 0, hz - POD_GRASP_BELOW_TOP)}
    return _build(obj_id, "coffee_pod", parts, kp, fixture=False, symmetry="z_continuous", mass=POD_MASS,
                  color=(0.84, 0.84, 0.84, 1.0))


def lid_angle(machine: ObjectSpec, state: SceneState) -> float:
    return joint_values(machine, state.joints)["lid"]


def lid_closed(machine: ObjectSpec, state: SceneState) -> bool:
    """coffee.py Coffee._check_lid: the hinge angle below 15 deg."""
    return bool(lid_angle(machine, state) < LID_CLOSED_TOLERANCE)


POD_MISS_ALLOWED = HOLDER_HALF[0] - POD_HALF[0]  # coffee.py r_diff: holder radius - pod radius (5.2 mm)


def pod_miss(holder: np.ndarray, pod: np.ndarray) -> float:
    """The pod centre's x-y distance from the holder's (world positions); _check_pod allows POD_MISS_ALLOWED."""
    return float(np.linalg.norm(np.asarray(pod, float)[:2] - np.asarray(holder, float)[:2]))


def pod_below_holder(holder: np.ndarray, pod: np.ndarray) -> bool:
    """_check_pod's second rule: the pod's bottom below the holder's bottom."""
    return bool(pod[2] - POD_HALF[2] < holder[2] - HOLDER_HALF[2])


def pod_in_holder(machine: ObjectSpec, pod: ObjectSpec, state: SceneState) -> bool:
    """coffee.py Coffee._check_pod: the pod's centre within r_diff = holder radius - pod radius (5.2 mm) of the
    holder's in x-y, its bottom not below the holder's bottom and its top not above the lid's underside."""
    m = state.poses[machine.id]
    holder = m.rotation.apply(machine.keypoint("pod_holder")) + m.position
    lid = link_point(machine, m, joint_values(machine, state.joints), "lid", "body_origin")
    p = state.poses[pod.id].position
    if pod_miss(holder, p) > POD_MISS_ALLOWED:
        return False
    return not (pod_below_holder(holder, p) or p[2] + POD_HALF[2] > lid[2] - LID_HALF[2])


def coffee_success(machine: ObjectSpec, pod: ObjectSpec, state: SceneState) -> bool:
    """coffee.py Coffee._get_partial_task_metrics()["task"]: lid check and pod check."""
    return lid_closed(machine, state) and pod_in_holder(machine, pod, state)


def lid_key(machine: ObjectSpec) -> str:
    return joint_key(machine.id, "lid")

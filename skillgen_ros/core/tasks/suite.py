"""The task suite: Square, PickPlace, NutAssembly, Threading, ThreePieceAssembly (+ clutter variants of
Square/PickPlace), Coffee and CoffeePreparation (the paper's Coffee Prep).

Reset regions are robosuite's / MimicGen's placement initializers, to the millimetre, in our world
frame (the Panda base, mounted as robosuite mounts it: core/robot.py). Those initializers give x/y
ranges relative to the table centre (`reference=table_offset`); `_rs` adds TABLE_CENTER_XY (0.56, 0).
Square's clutter variants are the paper's (SkillMimicGen appendix, "Presence of Clutter"): the D1 /
D2 regions plus one large obstruction with its own region near the workspace centre. PickPlace (not a
paper simulation task) keeps our own regions and its "clutter" variant.
docs/tasks.md lists every region (generated from this file by `regions_markdown()`).
Skill object_id is the skill's reference object (the frame its motion is expressed in): the
object grasped for a grasp skill, the target fixture for a place/insert skill.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import UnknownTaskError
from ..geometry import Pose
from ..robot import TABLE_CENTER_XY, TABLE_Z
from . import assembly as A
from . import coffee as C
from . import coffee_prep as CP
from . import objects as O
from .spec import ObjectSpec, Region, SceneState, SkillSpec, TaskSpec

PI = np.pi
FULL = (0.0, 2 * PI)   # robosuite / MimicGen nuts: z_rot (0, 2 pi)

# robosuite nut_assembly.py on_peg(): |dx|, |dy| < 0.03 and the nut body below table_offset z + 0.05
ON_PEG_XY = 0.03
ON_PEG_Z = 0.05
# robosuite nut_assembly.py _check_success(): r_reach = 1 - tanh(10 * |eef - nut|) must be < 0.6, i.e.
# the EE farther than atanh(0.4) / 10 = 0.0424 m from the nut body (the hand has let go or moved off)
R_REACH_MAX = 0.6
RELEASE_DISTANCE = float(np.arctanh(1.0 - R_REACH_MAX) / 10.0)


def _deg(a: float, b: float) -> tuple[float, float]:
    return (float(np.radians(a)), float(np.radians(b)))


def _rs(x: tuple[float, float], y: tuple[float, float], yaw: tuple[float, float] = (0.0, 0.0)) -> Region:
    """A robosuite / MimicGen placement range (x, y relative to the table centre) in our world frame."""
    cx, cy = TABLE_CENTER_XY
    return Region((round(cx + x[0], 6), round(cx + x[1], 6)), (round(cy + y[0], 6), round(cy + y[1], 6)),
                  (float(yaw[0]), float(yaw[1])))


def _world(pose: Pose, local) -> np.ndarray:
    return pose.rotation.apply(np.asarray(local, float)) + pose.position


def keypoint_world(obj: ObjectSpec, pose: Pose, name: str) -> np.ndarray:
    """`obj`'s keypoint `name` in the world with the object at `pose`: the point the success rules read."""
    return _world(pose, obj.keypoint(name))


def on_peg(nut: ObjectSpec, peg: ObjectSpec, poses) -> bool:
    """robosuite NutAssembly.on_peg: nut body within 3 cm of the peg body in world x and y, and
    below the table top + 5 cm (so at least 8 cm down the 13 cm peg)."""
    c = keypoint_world(nut, poses[nut.id], "body_origin")
    p = keypoint_world(peg, poses[peg.id], "body_origin")
    return bool(abs(c[0] - p[0]) < ON_PEG_XY and abs(c[1] - p[1]) < ON_PEG_XY and c[2] < TABLE_Z + ON_PEG_Z)


def hand_released(nut: ObjectSpec, state: SceneState) -> bool:
    """robosuite's r_reach < 0.6: the EE is more than RELEASE_DISTANCE (4.24 cm) from the nut body."""
    c = _world(state.poses[nut.id], nut.keypoint("body_origin"))
    r_reach = 1.0 - np.tanh(10.0 * float(np.linalg.norm(np.asarray(state.ee_position, float) - c)))
    return bool(r_reach < R_REACH_MAX)


def nut_on_peg(nut: ObjectSpec, peg: ObjectSpec, state: SceneState) -> bool:
    """robosuite NutAssembly._check_success for one nut: on_peg and r_reach < 0.6."""
    return on_peg(nut, peg, state.poses) and hand_released(nut, state)


def object_in_bin(obj: ObjectSpec, bin_: ObjectSpec, state: SceneState) -> bool:
    """The object's centre is inside the bin's inner footprint and low enough to be resting in it (ours)."""
    poses = state.poses
    b = poses[bin_.id]
    local = b.rotation.inv().apply(poses[obj.id].position - b.position)
    floor = _world(b, bin_.keypoint("floor_center"))[2]
    return bool(abs(local[0]) < O.BIN_INNER_HALF and abs(local[1]) < O.BIN_INNER_HALF
                and poses[obj.id].position[2] < floor + 2 * obj.half_extents[2] + 0.02)


def needle_through_ring(needle: ObjectSpec, tripod: ObjectSpec, state: SceneState) -> bool:
    """MimicGen Threading._check_success: the needle (shaft) geom's centre within ring_size[1] = 1.2 cm
    of the ring centre (the mean of the ring geoms), i.e. the shaft pushed half way through the ring."""
    shaft = _world(state.poses[needle.id], needle.keypoint("shaft_center"))
    ring = _world(state.poses[tripod.id], tripod.keypoint("ring_center"))
    return bool(np.linalg.norm(shaft - ring) < O.RING_SIZE[1])


def _fixed(x: float, y: float, yaw: float = 0.0) -> Region:
    return _rs((x, x), (y, y), (yaw, yaw))


# The clutter obstruction (O.obstacle, 10 x 10 x 16 cm): the paper places it "randomly near the center of
# the workspace" with its own distribution but gives no numbers; ours: +-4 cm x, +-6 cm y about the table
# centre, yaw +-45 deg.
OBSTACLE_REGION = _rs((-0.04, 0.04), (-0.06, 0.06), _deg(-45, 45))
# Coffee's: the same 8 x 12 cm box and yaw, moved from the table centre (which D0's machine fills) toward the
# robot until it clears the D0 machine: centred at x -0.10, y 0 about the table centre, between the robot and
# the machine. (A box on the pod-to-holder line crowds the pod: SkillGen's grasp initiation was in collision in
# 9-10 of 10-12 smoke attempts, and MimicGen, which pybullet lets push through, was unaffected.)
COFFEE_OBSTACLE_REGION = _rs((-0.14, -0.06), (-0.06, 0.06), _deg(-45, 45))
# PickPlace's own clutter obstacle region (not a paper task).
PICKPLACE_OBSTACLE_REGION = Region((0.50, 0.58), (-0.06, 0.06), _deg(-45, 45))
# robosuite pegs_arena.xml: peg1 (square) at (0.23, 0.1), peg2 (round) at (0.23, -0.1) from the table centre.
SQUARE_PEG_XY, ROUND_PEG_XY = (0.23, 0.10), (0.23, -0.10)


def _square() -> TaskSpec:
    nut, peg = O.square_nut(), O.square_peg()
    # MimicGen mimicgen/envs/robosuite/nut_assembly.py: Square_D0 (peg fixed at robosuite's peg1, nut
    # x (-0.115, -0.11) y (0.11, 0.225) z_rot (0, 2 pi)), Square_D1 (nut x (-0.115, 0.115) y (-0.255, 0.255);
    # peg x (-0.1, 0.3) y (-0.2, 0.2) z_rot 0), Square_D2 (nut and peg x, y (-0.25, 0.25); peg z_rot (0, pi/2)).
    # The peg is sampled first and the nut kept off it, as Square_D1._reset_internal does.
    d1 = {"square_peg": _rs((-0.1, 0.3), (-0.2, 0.2)), "square_nut": _rs((-0.115, 0.115), (-0.255, 0.255), FULL)}
    d2 = {"square_peg": _rs((-0.25, 0.25), (-0.25, 0.25), (0.0, PI / 2)),
          "square_nut": _rs((-0.25, 0.25), (-0.25, 0.25), FULL)}
    table = {
        "D0": {"square_peg": _fixed(*SQUARE_PEG_XY), "square_nut": _rs((-0.115, -0.11), (0.11, 0.225), FULL)},
        "D1": d1,
        "D2": d2,
        "D1_clutter": {**d1, "obstacle": OBSTACLE_REGION},
        "D2_clutter": {**d2, "obstacle": OBSTACLE_REGION},
    }
    skills = (SkillSpec(0, "square_nut", "grasp_nut", "transit"),
              SkillSpec(1, "square_peg", "place_on_peg", "transfer", "square_nut"))
    return TaskSpec("Square", (nut, peg), skills, tuple(table), table,
                    lambda s: nut_on_peg(nut, peg, s), O.obstacle(), ("D1_clutter", "D2_clutter"))


def _pick_place() -> TaskSpec:
    """Ours (robosuite's PickPlace is a bin-to-bin task the paper does not use): regions in our frame."""
    m, b = O.milk(), O.bin_()
    d1 = {"bin": Region((0.55, 0.55), (0.19, 0.19)), "milk": Region((0.42, 0.62), (-0.30, -0.08), _deg(-45, 45))}
    table = {
        "D0": {"bin": Region((0.55, 0.55), (0.19, 0.19)),
               "milk": Region((0.50, 0.56), (-0.20, -0.14), _deg(-45, 45))},
        "D1": d1,
        "D2": {"bin": Region((0.45, 0.65), (0.14, 0.24), _deg(-45, 45)),
               "milk": Region((0.40, 0.66), (-0.30, -0.04), _deg(-45, 45))},
        "clutter": {**d1, "obstacle": PICKPLACE_OBSTACLE_REGION},
    }
    skills = (SkillSpec(0, "milk", "grasp_milk", "transit"), SkillSpec(1, "bin", "place_in_bin", "transfer", "milk"))
    return TaskSpec("PickPlace", (m, b), skills, tuple(table), table,
                    lambda s: object_in_bin(m, b, s), O.obstacle(), ("clutter",))


def _nut_assembly() -> TaskSpec:
    sn, rn, sp, rp = O.square_nut(), O.round_nut(), O.square_peg(), O.round_peg()
    # D0: MimicGen NutAssembly_D0 (pegs at robosuite's pegs_arena.xml positions; square nut x (-0.115, -0.11)
    # y (0.11, 0.225), round nut y (-0.225, -0.11), z_rot (0, 2 pi)). D1 / D2 are SkillMimicGen's own; the
    # paper's appendix gives their sizes (D1: nuts 0.23 x 0.51 random yaw, pegs 0.4 x 0.4 fixed yaw; D2:
    # 0.5 x 0.5 for all, random yaw); we place them where MimicGen's Square_D1 / Square_D2 put the same sizes.
    nut1, peg1 = _rs((-0.115, 0.115), (-0.255, 0.255), FULL), _rs((-0.1, 0.3), (-0.2, 0.2))
    all2 = _rs((-0.25, 0.25), (-0.25, 0.25), FULL)
    peg2 = _rs((-0.25, 0.25), (-0.25, 0.25), (0.0, PI / 2))
    table = {
        "D0": {"square_peg": _fixed(*SQUARE_PEG_XY), "round_peg": _fixed(*ROUND_PEG_XY),
               "square_nut": _rs((-0.115, -0.11), (0.11, 0.225), FULL),
               "round_nut": _rs((-0.115, -0.11), (-0.225, -0.11), FULL)},
        "D1": {"square_peg": peg1, "round_peg": peg1, "square_nut": nut1, "round_nut": nut1},
        "D2": {"square_peg": peg2, "round_peg": peg2, "square_nut": all2, "round_nut": all2},
    }
    skills = (SkillSpec(0, "square_nut", "grasp_square_nut", "transit"),
              SkillSpec(1, "square_peg", "place_on_square_peg", "transfer", "square_nut"),
              SkillSpec(2, "round_nut", "grasp_round_nut", "transit"),
              SkillSpec(3, "round_peg", "place_on_round_peg", "transfer", "round_nut"))
    return TaskSpec("NutAssembly", (sn, rn, sp, rp), skills, tuple(table), table,
                    lambda s: nut_on_peg(sn, sp, s) and nut_on_peg(rn, rp, s))


# MimicGen's needle points its tip along its body -y; ours along +x: our yaw = MimicGen z_rot - 90 deg.
NEEDLE_YAW_OFFSET = -90.0


def _needle(x, y, z_rot_deg) -> Region:
    return _rs(x, y, _deg(z_rot_deg[0] + NEEDLE_YAW_OFFSET, z_rot_deg[1] + NEEDLE_YAW_OFFSET))


def _threading() -> TaskSpec:
    nd, tp = O.needle(), O.tripod()
    # MimicGen mimicgen/envs/robosuite/threading.py _get_initial_placement_bounds (needle sampled first):
    # D0 needle x (-0.2, -0.05) y (0.15, 0.25) z_rot (-120, -60) deg, tripod fixed (0, -0.15) at 90 deg;
    # D1 needle x (-0.2, 0.05) y (0.15, 0.25) z_rot (-210, 30), tripod x (-0.1, 0.15) y (-0.2, -0.1) z_rot (30, 150);
    # D2 needle y (-0.25, -0.15), tripod y (0.1, 0.2) z_rot (-150, -30), the rest as D1.
    table = {
        "D0": {"needle": _needle((-0.2, -0.05), (0.15, 0.25), (-120, -60)), "tripod": _fixed(0.0, -0.15, PI / 2)},
        "D1": {"needle": _needle((-0.2, 0.05), (0.15, 0.25), (-210, 30)),
               "tripod": _rs((-0.1, 0.15), (-0.2, -0.1), _deg(30, 150))},
        "D2": {"needle": _needle((-0.2, 0.05), (-0.25, -0.15), (-210, 30)),
               "tripod": _rs((-0.1, 0.15), (0.1, 0.2), _deg(-150, -30))},
    }
    skills = (SkillSpec(0, "needle", "grasp_needle", "transit"),
              SkillSpec(1, "tripod", "thread_tripod", "transfer", "needle"))
    # The needle's 1 x 1 cm shaft, partly hidden behind its handle from the front camera, is found at reset in
    # 0/10 scenes at 128x128, 4/10 at 256x256 and 10/10 at 480x360 (docs/perception.md, 2026-12-06).
    return TaskSpec("Threading", (nd, tp), skills, tuple(table), table, lambda s: needle_through_ring(nd, tp, s),
                    camera_size=(480, 360))


def _three_piece_assembly() -> TaskSpec:
    b, p1, p2 = A.base(), A.piece_1(), A.piece_2()
    # MimicGen mimicgen/envs/robosuite/three_piece_assembly.py _get_initial_placement_bounds, sampled base,
    # piece_1, piece_2 (SequentialCompositeSampler order), x / y relative to the table centre:
    # D0 base fixed (0, 0) z_rot 0, pieces x, y (-0.22, 0.22) z_rot 1.5708; D1 the base too in x, y (-0.22, 0.22);
    # D2 base z_rot (-pi/4, pi/4), pieces z_rot (1.5708 - pi/2, 1.5708 + pi/2).
    box = (-0.22, 0.22)
    piece = _rs(box, box, (PI / 2, PI / 2))
    piece2 = _rs(box, box, (0.0, PI))
    table = {
        "D0": {"base": _fixed(0.0, 0.0), "piece_1": piece, "piece_2": piece},
        "D1": {"base": _rs(box, box), "piece_1": piece, "piece_2": piece},
        "D2": {"base": _rs(box, box, (-PI / 4, PI / 4)), "piece_1": piece2, "piece_2": piece2},
    }
    skills = (SkillSpec(0, "piece_1", "grasp_piece_1", "transit"),
              SkillSpec(1, "base", "insert_piece_1_into_base", "transfer", "piece_1"),
              SkillSpec(2, "piece_2", "grasp_piece_2", "transit"),
              SkillSpec(3, "piece_1", "insert_piece_2_into_piece_1", "transfer", "piece_2"))
    return TaskSpec("ThreePieceAssembly", (b, p1, p2), skills, tuple(table), table,
                    lambda s: A.assembled(b, p1, p2, s))


def _coffee() -> TaskSpec:
    m, pod = C.coffee_machine(), C.coffee_pod()
    # MimicGen mimicgen/envs/robosuite/coffee.py _get_initial_placement_bounds (machine sampled first, then the
    # pod), x / y relative to the table centre: Coffee (D0) machine fixed (0, -0.1) z_rot -pi/6, pod x (-0.13, -0.07)
    # y (0.17, 0.23) z_rot 0; Coffee_D1 machine x (0.05, 0.15) y (-0.2, -0.1) z_rot (-pi/6, pi/3), pod x (-0.2, 0.05)
    # y (0.17, 0.3); Coffee_D2 machine x (-0.05, 0.05) y (0.1, 0.2) z_rot (2 pi/3, 7 pi/6), pod y (-0.3, -0.17).
    pod_xy = (-0.2, 0.05)
    d0 = {"coffee_machine": _fixed(0.0, -0.1, -PI / 6), "coffee_pod": _rs((-0.13, -0.07), (0.17, 0.23))}
    d1 = {"coffee_machine": _rs((0.05, 0.15), (-0.2, -0.1), (-PI / 6, PI / 3)), "coffee_pod": _rs(pod_xy, (0.17, 0.3))}
    table = {
        "D0": d0,
        "D1": d1,
        "D2": {"coffee_machine": _rs((-0.05, 0.05), (0.1, 0.2), (2 * PI / 3, 7 * PI / 6)),
               "coffee_pod": _rs(pod_xy, (-0.3, -0.17))},
        # the paper's Coffee (D0, Clutter) / (D1, Clutter): its clutter table, same source demos (D0)
        "D0_clutter": {**d0, "obstacle": COFFEE_OBSTACLE_REGION},
        "D1_clutter": {**d1, "obstacle": COFFEE_OBSTACLE_REGION},
    }
    # SkillMimicGen appendix "Tasks and Task Variants": grasp pod, insert-into and close machine
    skills = (SkillSpec(0, "coffee_pod", "grasp_pod", "transit"),
              SkillSpec(1, "coffee_machine", "insert_pod_and_close_lid", "transfer", "coffee_pod"))
    # box footprints: the machine's bounding circle (r 17 cm) would keep the obstacle far off the machine;
    # D0-D2 resets are the same as with circles (no draw is rejected either way)
    return TaskSpec("Coffee", (m, pod), skills, tuple(table), table, lambda s: C.coffee_success(m, pod, s),
                    O.obstacle(), ("D0_clutter", "D1_clutter"), footprint="box")


def _coffee_preparation() -> TaskSpec:
    """MimicGen's CoffeePreparation (the paper's Coffee Prep; named as MimicGen's environment, like the suite's
    other tasks): D0 / D1 MimicGen's, D2 SkillMimicGen's own (D0 with the drawer and the mug swapped sides)."""
    cab, m, mug, pod = CP.drawer(), CP.machine(), CP.mug(), C.coffee_pod()
    # MimicGen mimicgen/envs/robosuite/coffee.py CoffeePreparation._get_initial_placement_bounds, sampled drawer,
    # machine, mug (SequentialCompositeSampler), then the pod in the drawer; x / y relative to the table centre:
    # D0 drawer fixed (0.15, -0.35) z_rot pi, machine fixed (-0.15, -0.25) z_rot -pi/6, mug x (0.05, 0.20)
    # y (0.05, 0.25) z_rot 0; CoffeePreparation_D1 machine x (-0.25, -0.15) y (-0.30, -0.25) z_rot (-pi/6, pi/6),
    # mug x (-0.15, 0.20) y (0.05, 0.25) z_rot (0, 2 pi). The pod: x (-0.03, 0.03) y (-0.05, 0.03) from the drawer
    # bottom's centre in the drawer frame (both variants), on the drawer's tray (coffee_prep.py).
    # The paper's D0 mug region is 0.15 x 0.15 m; MimicGen's code (where its and the paper's D0 demos come from)
    # is 0.15 x 0.20: we keep the code's.
    # The pod's yaw: 0 in the world, not the sampler's z_rot 0 in the drawer (pi in the world for D0's drawer). The
    # pod is a cylinder (z_continuous), so both are the same scene, but the estimating perception labels a
    # z-symmetric object yaw 0: with demos recorded at pi every estimated-pose attempt replayed the pod grasp turned
    # 180 deg (D0 ground truth with the demos at pi, attempts 0-19: pod labelled pi 11/20, labelled 0 7/20).
    def pod_in(drawer: Region) -> Region:
        px, py = CP.pod_in_drawer_xy((drawer.x[0], drawer.y[0]), drawer.yaw[0])
        return Region(px, py, (0.0, 0.0), z=CP.pod_on_tray_z(cab, TABLE_Z))

    drawer = _fixed(0.15, -0.35, PI)
    # D2 (SkillMimicGen's own; appendix: "Same task as D0 but the drawer is placed on the right side of the table,
    # and the mug is initialized on the left side of the table, instead of the right"; no numbers): D0 mirrored in
    # y for the drawer and the mug, the machine kept. The drawer at (0.15, +0.35) with yaw 0, D0's yaw pi mirrored
    # (the cabinet is symmetric in its x, so the mirror image is the turned cabinet; its front faces the table's
    # centre as in D0, and its yaw stays a multiple of 90 deg as pod_in_drawer_xy needs); the mug in D0's
    # 0.15 x 0.20 m box mirrored, y (-0.25, -0.05), at D0's yaw 0 ("same task as D0": its top-down rotation fixed
    # as D0's; the mirror image would be yaw pi, which turns the D0 demos' pitched mug grasp out of the wrist's
    # range: ground truth 0/10, IK_FAILED 7, docs/coffee_prep.md); the pod in the drawer as in D0.
    drawer_d2 = _fixed(0.15, 0.35, 0.0)
    table = {
        "D0": {"drawer": drawer, "coffee_machine": _fixed(-0.15, -0.25, -PI / 6),
               "mug": _rs((0.05, 0.20), (0.05, 0.25)), "coffee_pod": pod_in(drawer)},
        "D1": {"drawer": drawer, "coffee_machine": _rs((-0.25, -0.15), (-0.30, -0.25), (-PI / 6, PI / 6)),
               "mug": _rs((-0.15, 0.20), (0.05, 0.25), FULL), "coffee_pod": pod_in(drawer)},
        "D2": {"drawer": drawer_d2, "coffee_machine": _fixed(-0.15, -0.25, -PI / 6),
               "mug": _rs((0.05, 0.20), (-0.25, -0.05)), "coffee_pod": pod_in(drawer_d2)},
    }
    # SkillMimicGen appendix "Tasks and Task Variants": grasp mug, place onto machine and open lid, open drawer,
    # grasp pod, insert into machine and close lid (MimicGen's coffee_preparation subtasks and object_refs)
    skills = (SkillSpec(0, "mug", "grasp_mug", "transit"),
              SkillSpec(1, "coffee_machine", "place_mug_and_open_lid", "transfer", "mug"),
              SkillSpec(2, "drawer", "open_drawer", "transit"),
              SkillSpec(3, "coffee_pod", "grasp_pod", "transit"),
              SkillSpec(4, "coffee_machine", "insert_pod_and_close_lid", "transfer", "coffee_pod"))
    # The pod lies in the closed drawer at reset (MimicGen's CoffeePreparation): the front camera sees it only once
    # skill 2 pulled the drawer open, so perception requires it from skill 3 (grasp_pod) on, not at reset.
    return TaskSpec("CoffeePreparation", (cab, m, mug, pod), skills, tuple(table), table,
                    lambda s: CP.coffee_preparation_success(m, pod, mug, s), footprint="box",
                    hidden_until={"coffee_pod": 3})


_BUILDERS = {"Square": _square, "PickPlace": _pick_place, "NutAssembly": _nut_assembly, "Threading": _threading,
             "ThreePieceAssembly": _three_piece_assembly, "Coffee": _coffee, "CoffeePreparation": _coffee_preparation}
TASK_NAMES: tuple[str, ...] = tuple(_BUILDERS)
_CACHE: dict[str, TaskSpec] = {}


def get_task(name: str) -> TaskSpec:
    """The TaskSpec for `name` (one of TASK_NAMES); UnknownTaskError otherwise."""
    if name not in _BUILDERS:
        raise UnknownTaskError(f"unknown task {name!r}; known: {list(TASK_NAMES)}")
    if name not in _CACHE:
        _CACHE[name] = _BUILDERS[name]()
    return _CACHE[name]


def _task_object(object_type: str, object_id: str, accept) -> ObjectSpec | None:
    """The first task object of `object_type` that `accept(spec)` takes, under the scene's id (a node that
    gets only a SceneObject names it by type), or None."""
    for name in _BUILDERS:
        for o in get_task(name).objects:
            if o.type == object_type and accept(o):
                return o if o.id == object_id else replace(o, id=object_id)
    return None


def articulated_object(object_type: str, object_id: str) -> ObjectSpec | None:
    """The articulated ObjectSpec of `object_type` (a SceneObject's type) under the scene's id, or None if no
    task has an articulated object of that type: how a node that gets only a SceneObject poses its links."""
    return _task_object(object_type, object_id, lambda o: bool(o.joints))


def scene_object_spec(object_type: str, object_id: str, half_extents) -> ObjectSpec | None:
    """The ObjectSpec of `object_type` under the scene's id when a task has an object of that type with
    these bounding-box half extents (to 0.1 mm), else None: how a node that gets only a SceneObject
    plans around its parts (a drawer's walls, not the box around them) as generation in-process does."""
    h = np.asarray(half_extents, float)
    if h.shape != (3,):
        return None
    return _task_object(object_type, object_id, lambda o: np.allclose(o.half_extents, h, atol=1e-4))


def regions_markdown() -> str:
    """The docs/tasks.md table of every variant's reset regions (regenerate when regions change)."""
    rows = ["| task | variant | object | x range (m) | y range (m) | yaw range (deg) |", "|---|---|---|---|---|---|"]
    for name in _BUILDERS:
        t = get_task(name)
        for v in t.variants:
            for oid, r in t.regions(v).items():
                yaw = np.degrees(r.yaw)
                rows.append(f"| {name} | {v} | {oid} | [{r.x[0]:.3f}, {r.x[1]:.3f}] | [{r.y[0]:.3f}, {r.y[1]:.3f}] "
                            f"| [{yaw[0]:.0f}, {yaw[1]:.0f}] |")
    return "\n".join(rows)

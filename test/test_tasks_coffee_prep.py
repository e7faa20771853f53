"""Coffee Prep (CoffeePreparation) pinned to its reference: NVlabs/mimicgen mimicgen/envs/robosuite/coffee.py
(CoffeePreparation / CoffeePreparation_D1: _get_initial_placement_bounds, _reset_internal, _check_mug_placement,
_get_partial_task_metrics), assets/objects/drawer_long.xml, assets/shapenet_core/mugs/3143a4ac; region sizes from
the SkillMimicGen appendix "Tasks and Task Variants". The objects built and moved in the pybullet world.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.robot import Q_HOME, TABLE_CENTER_XY, TABLE_Z
from skillgen_ros.core.tasks import SceneState, get_task
from skillgen_ros.core.tasks import coffee as C
from skillgen_ros.core.tasks import coffee_prep as CP
from skillgen_ros.core.generation.mimicgen import spec_for
from skillgen_ros.core.planning.articulated import link_boxes
from skillgen_ros.core.tasks.articulation import initial_joint_values, joint_key, link_point, posed_link_parts
from skillgen_ros.core.tasks.shapes import aabb, read_obj
from skillgen_ros.core.tasks.skill_points import SKILL_POINTS, skill_point_world
from skillgen_ros.core.tasks.spec import SEPARATION_MARGIN, boxes_overlap
from skillgen_ros.core.tasks.suite import TASK_NAMES
from helpers.regions import assert_widths_match

TASK = get_task("CoffeePreparation")
M, POD, MUG, CAB = (TASK.object(k) for k in ("coffee_machine", "coffee_pod", "mug", "drawer"))
FAR = np.array([0.40, 0.0, 0.40])
LID, SLIDE = joint_key("coffee_machine", "lid"), joint_key("drawer", "slide")
SEATED_Z = -C.HOLDER_HALF_H + 2 * C.HOLDER_BASE_HALF_H + C.HOLDER_BASE_OFFSET + C.POD_HALF[2]  # on the cup base


def test_registered_with_the_papers_five_skills():
    assert "CoffeePreparation" in TASK_NAMES
    assert TASK.variants == ("D0", "D1", "D2") and TASK.footprint == "box"
    # SkillMimicGen appendix: grasp mug, place onto machine and open lid, open drawer, grasp pod, insert and close;
    # object_refs as MimicGen's coffee_preparation subtasks: mug, coffee_machine, drawer, coffee_pod, coffee_machine
    assert [(s.name, s.object_id, s.mode, s.attached_object) for s in TASK.skills] == [
        ("grasp_mug", "mug", "transit", None), ("place_mug_and_open_lid", "coffee_machine", "transfer", "mug"),
        ("open_drawer", "drawer", "transit", None), ("grasp_pod", "coffee_pod", "transit", None),
        ("insert_pod_and_close_lid", "coffee_machine", "transfer", "coffee_pod")]
    assert len(SKILL_POINTS["CoffeePreparation"]) == len(TASK.skills)
    for sk in TASK.skills:   # raises if the object lacks the keypoint (the drawer's handle: 20.8 cm out in y)
        assert np.all(np.abs(skill_point_world(TASK, sk.index, Pose(np.zeros(3), [0, 0, 0, 1.0]))) < 0.21)
    # generate_core_configs.py coffee_preparation: random, [5, 10] for each of its 4 subtask ends
    assert (spec_for("CoffeePreparation").selection, spec_for("CoffeePreparation").offset_range) == ("random", (5, 10))


def test_drawer_geometry_is_drawer_long_xml():
    # the cabinet: x +-(0.11 + 0.008), y -0.163 - 0.012 .. -0.0315 + 0.1435, z 0.004 - 0.014 .. 0.121 + 0.008
    assert CAB.half_extents == pytest.approx((0.118, 0.1435, 0.0695)) and CAB.is_fixture and len(CAB.parts) == 7
    assert CAB.keypoint("body_origin") == pytest.approx((0.0, 0.0315, -0.0595))   # the base body in our frame
    (slide,) = CAB.joints
    assert (slide.type, slide.axis, slide.lower, slide.upper, slide.initial) == ("prismatic", (0.0, 1.0, 0.0), -1.0, 0.0, 0.0)
    assert slide.damping == 100.0 and CAB.links[0].mass == pytest.approx(7.85398)
    assert np.asarray(slide.origin) - CAB.keypoint("body_origin") == pytest.approx((0.0, -0.01, 0.076))  # drawer_link
    assert len(CAB.links[0].parts) == 8   # 4 tray boxes, drawer_bottom, 3 handle capsules
    # drawer_bottom's top (the pod's floor) 5.4 cm over the base body; the handle bar's front 22.9 cm before it
    assert CAB.keypoint("tray_top") - CAB.keypoint("body_origin") == pytest.approx((0.0, -0.05, 0.054))
    assert CAB.keypoint("handle") - CAB.keypoint("body_origin") == pytest.approx((0.0, -0.239, 0.116))


def test_the_pod_sits_on_the_closed_drawers_bottom_5_mm_higher_than_mimicgens():
    # _reset_internal: drawer_bottom's top (0.054 over the base body) + the pod's bottom offset + 1 mm; MimicGen's
    # base body is 5 mm over the table (z 0.805), ours 10 mm (its bottom surface rests on the table)
    ours = CP.pod_on_tray_z(CAB, TABLE_Z) - TABLE_Z
    assert ours == pytest.approx(0.010 + 0.054 + C.POD_HALF[2] + 0.001)
    assert ours - (0.805 - 0.8 + 0.054 + C.POD_HALF[2] + 0.001) == pytest.approx(CP.CABINET_SINK)
    with pytest.raises(InvalidInputError):
        CP.pod_in_drawer_xy((0.7, -0.35), 0.3)   # a turned cabinet has no axis-aligned pod box


def test_meshes_and_planner_boxes_follow_the_links():
    for o in (CAB, M, MUG):
        v, f = read_obj(o.mesh_path)
        lo, hi = aabb(o.parts + posed_link_parts(o.links, o.joints))   # the links at their reset values
        np.testing.assert_allclose(v.min(0), lo, atol=1e-4)
        np.testing.assert_allclose(v.max(0), hi, atol=1e-4)
        lo, hi = aabb(o.parts)   # the object frame: the fixed base's (or the free body's) box centre
        np.testing.assert_allclose((hi + lo) / 2, 0.0, atol=1e-9)
        np.testing.assert_allclose((hi - lo) / 2, o.half_extents, atol=1e-9)
    # the drawer's link as planner boxes: pulled 0.2 m, every box 0.2 m along the world's +y (cabinet yaw pi)
    pose = Pose([0.71, -0.3185, TABLE_Z + CAB.half_extents[2]], Rotation.from_euler("z", np.pi).as_quat())
    closed, out = link_boxes(CAB, pose, {SLIDE: 0.0}), link_boxes(CAB, pose, {SLIDE: -0.2})
    assert len(closed) == 8 and all(b.name == "drawer" for b in closed)
    for a, b in zip(closed, out):
        assert b.pose[:3, 3] - a.pose[:3, 3] == pytest.approx([0.0, 0.2, 0.0], abs=1e-12)


def test_mug_geometry_is_shapenet_3143a4ac():
    # model.xml: bottom_site z -0.03864, top_site z 0.04183; collision hulls x +-0.0353, y -0.05785 .. 0.04409
    assert MUG.half_extents[2] == pytest.approx((0.04183 + 0.03864) / 2)
    assert MUG.half_extents[0] == pytest.approx(0.0353 * np.cos(np.pi / 12))   # the 12-box ring's flat faces
    assert 2 * MUG.half_extents[1] == pytest.approx(0.04409 - (-0.02255 - 0.0353 * np.cos(np.pi / 12)))
    assert not MUG.is_fixture and len(MUG.parts) == 16   # a free body: one pybullet compound holds 16
    assert MUG.mass == pytest.approx(0.0116, abs=5e-4)    # density 100 (coffee.py _get_mug_model)
    assert MUG.keypoint("axis_bottom")[2] == pytest.approx(-MUG.half_extents[2])
    assert MUG.keypoint("axis_bottom")[1] - MUG.keypoint("body_origin")[1] == pytest.approx(-0.02255)


def test_machine_is_coffees_with_the_lid_closed_at_reset():
    coffee = get_task("Coffee").object("coffee_machine")
    assert M.parts == coffee.parts and M.half_extents == coffee.half_extents   # add_cup=False: as Coffee's
    assert M.type == "coffee_machine_closed" and M.mesh_path != coffee.mesh_path
    assert M.joints[0].initial == 0.0 and coffee.joints[0].initial == pytest.approx(2 * np.pi / 3)
    # the drip base's top, where the mug stands: 1 cm over the table, under the pod holder
    assert M.keypoint("base_top") == pytest.approx((0.0, 0.1005, -C.BODY_HALF[2] + 2 * C.BASE_HALF[2]))
    assert initial_joint_values(TASK.objects) == {SLIDE: 0.0, LID: 0.0}


def _state(lid_deg=0.0, pod_dxy=(0.0, 0.0), mug_dz=0.0, mug_dxy=(0.0, 0.0), mug_tilt_deg=0.0, slide=0.0,
           joints=None, pod_dz=0.0) -> SceneState:
    """The machine at D1-like pose, the pod seated, the mug upright on the drip base under the holder."""
    m = Pose([0.40, -0.27, TABLE_Z + M.half_extents[2]], Rotation.from_euler("z", 0.3).as_quat())
    to_world = lambda local: m.rotation.apply(local) + m.position   # noqa: E731
    pod = Pose(to_world([pod_dxy[0], C.HOLDER_POS[1] + pod_dxy[1], C.HOLDER_POS[2] + SEATED_Z + pod_dz]), m.quaternion)
    yaw = m.rotation * Rotation.from_euler("z", 1.0)        # the handle any way round
    R = yaw * Rotation.from_euler("x", np.radians(mug_tilt_deg))
    bottom = to_world(M.keypoint("base_top") + [mug_dxy[0], mug_dxy[1], mug_dz])
    mug = Pose(bottom - R.apply(MUG.keypoint("axis_bottom")), R.as_quat())
    cab = Pose([0.71, -0.3185, TABLE_Z + CAB.half_extents[2]], Rotation.from_euler("z", np.pi).as_quat())
    js = {LID: np.radians(lid_deg), SLIDE: slide} if joints is None else joints
    return SceneState({"coffee_machine": m, "coffee_pod": pod, "mug": mug, "drawer": cab}, FAR, -1.0, js)


def test_mimicgen_success_rule_and_each_single_violation():
    assert TASK.is_success(_state())
    assert TASK.is_success(_state(slide=-0.25))              # MimicGen does not ask for the drawer closed
    assert not TASK.is_success(_state(lid_deg=20.0))         # _check_lid: hinge < 15 deg
    assert not TASK.is_success(_state(pod_dxy=(0.0, 0.006)))  # _check_pod: r_diff = 5.2 mm
    assert not TASK.is_success(_state(pod_dz=C.POD_HALF[2]))  # the pod half in the holder: its top over the lid's underside
    assert C.pod_in_holder(M, POD, _state(lid_deg=120.0, pod_dz=C.POD_HALF[2]))   # ... which only the closed lid forbids
    s = _state()
    s.poses["coffee_pod"] = Pose([0.7, -0.27, -0.004], [0, 0, 0, 1])   # the pod still in the drawer
    assert not TASK.is_success(s)
    # _check_mug_placement: upright (1 - cos(tilt) < 1e-3: 2.56 deg) ...
    assert TASK.is_success(_state(mug_tilt_deg=2.5)) and not TASK.is_success(_state(mug_tilt_deg=2.7))
    # ... and touching the base plate: 1 mm over it at most (the mug's margin), into it up to 5 mm (ours)
    assert TASK.is_success(_state(mug_dz=0.0009)) and not TASK.is_success(_state(mug_dz=0.002))
    assert TASK.is_success(_state(mug_dz=-0.004)) and not TASK.is_success(_state(mug_dz=-0.006))
    # the bottom disk must overlap the 8.4 x 10 cm plate: off its x edge by more than the mug's radius fails
    assert TASK.is_success(_state(mug_dxy=(C.BASE_HALF[0] + 0.03, 0.0)))
    assert not TASK.is_success(_state(mug_dxy=(C.BASE_HALF[0] + 0.036, 0.0)))
    # the mug upright on the table beside the machine: 1 cm under the plate's top
    s = _state()
    s.poses["mug"] = Pose([0.6, 0.1, TABLE_Z + MUG.half_extents[2]], [0, 0, 0, 1])
    assert CP.mug_upright(MUG, s) and not TASK.is_success(s)
    assert C.coffee_success(M, POD, s)   # Coffee's part alone still holds
    # ... and right against the plate's side (its disk over the plate's edge in x-y, its bottom on the table)
    m = s.poses["coffee_machine"]
    bottom = m.rotation.apply(M.keypoint("base_top") + [C.BASE_HALF[0] + CP.MUG_R_OUT - 0.002, 0.0, 0.0]) + m.position
    bottom[2] = TABLE_Z
    s.poses["mug"] = Pose(bottom - MUG.keypoint("axis_bottom"), [0, 0, 0, 1])
    assert CP.mug_upright(MUG, s) and not CP.mug_on_base(M, MUG, s) and not TASK.is_success(s)


def test_missing_joint_state_is_a_clear_error():
    with pytest.raises(InvalidInputError) as e:
        TASK.is_success(_state(joints={SLIDE: 0.0}))
    assert e.value.reason == "MISSING_JOINT_STATE"


PAPER = {  # SkillMimicGen appendix: (x width, y width, yaw range deg)
    ("D0", "drawer"): (0.0, 0.0, 0), ("D0", "coffee_machine"): (0.0, 0.0, 0),
    ("D0", "mug"): (0.15, 0.20, 0),        # paper 0.15 x 0.15; MimicGen's code 0.15 x 0.20 (kept: docs/tasks.md)
    ("D0", "coffee_pod"): (0.06, 0.08, 0),
    ("D1", "drawer"): (0.0, 0.0, 0), ("D1", "coffee_machine"): (0.1, 0.05, 60),
    ("D1", "mug"): (0.35, 0.2, 360), ("D1", "coffee_pod"): (0.06, 0.08, 0),
    # D2: "same task as D0" with the drawer and the mug on the other sides: D0's sizes (suite.py)
    ("D2", "drawer"): (0.0, 0.0, 0), ("D2", "coffee_machine"): (0.0, 0.0, 0),
    ("D2", "mug"): (0.15, 0.20, 0), ("D2", "coffee_pod"): (0.06, 0.08, 0),
}


def test_region_widths_match_the_paper_to_the_millimetre():
    assert_widths_match(TASK, PAPER)


def test_region_positions_follow_mimicgen_placement_bounds():
    cx = TABLE_CENTER_XY[0]
    d0, d1 = TASK.regions("D0"), TASK.regions("D1")
    for d in (d0, d1):
        assert d["drawer"].x == pytest.approx((cx + 0.15,) * 2) and d["drawer"].y == pytest.approx((-0.35, -0.35))
        assert d["drawer"].yaw == pytest.approx((np.pi, np.pi))
        # the pod: x (-0.03, 0.03), y (-0.05, 0.03) from drawer_bottom's centre (0, -0.05) in the drawer frame; its
        # yaw 0 in the world, as the estimating perception labels the z-symmetric pod (suite.py)
        assert d["coffee_pod"].yaw == pytest.approx((0.0, 0.0)) and POD.symmetry == "z_continuous"
        assert d["coffee_pod"].x == pytest.approx((cx + 0.12, cx + 0.18))
        assert d["coffee_pod"].y == pytest.approx((-0.35 + 0.05 - 0.03, -0.35 + 0.05 + 0.05))
    assert d0["coffee_machine"].x == pytest.approx((cx - 0.15,) * 2) and d0["coffee_machine"].y == pytest.approx((-0.25,) * 2)
    assert np.degrees(d0["coffee_machine"].yaw) == pytest.approx((-30.0, -30.0))
    assert d0["mug"].x == pytest.approx((cx + 0.05, cx + 0.2)) and d0["mug"].y == pytest.approx((0.05, 0.25))
    assert d1["coffee_machine"].x == pytest.approx((cx - 0.25, cx - 0.15)) and d1["coffee_machine"].y == pytest.approx((-0.3, -0.25))
    assert np.degrees(d1["coffee_machine"].yaw) == pytest.approx((-30.0, 30.0))
    assert d1["mug"].x == pytest.approx((cx - 0.15, cx + 0.2)) and d1["mug"].yaw == pytest.approx((0.0, 2 * np.pi))


def test_d2_is_d0_with_the_drawer_and_the_mug_mirrored_across_the_table():
    """SkillMimicGen's D2 (no numbers in the paper): D0's drawer and mug regions mirrored in y, the machine kept;
    the drawer turned to yaw 0 (its mirror image: the cabinet is symmetric in x), so its pod box mirrors too."""
    d0, d2 = TASK.regions("D0"), TASK.regions("D2")
    mirror = lambda y: (-y[1], -y[0])   # noqa: E731
    for oid in ("drawer", "mug", "coffee_pod"):
        assert d2[oid].x == pytest.approx(d0[oid].x) and d2[oid].y == pytest.approx(mirror(d0[oid].y)), oid
    assert d2["drawer"].yaw == pytest.approx((0.0, 0.0)) and d2["coffee_pod"].yaw == pytest.approx((0.0, 0.0))
    assert d2["mug"].yaw == d0["mug"].yaw and d2["coffee_machine"] == d0["coffee_machine"]
    assert d2["drawer"].y[0] > 0 > d2["mug"].y[1]   # the drawer on the table's +y side, the mug on its -y side
    assert d0["drawer"].y[0] < 0 < d0["mug"].y[0]
    assert d2["coffee_pod"].z == pytest.approx(d0["coffee_pod"].z)


@pytest.mark.parametrize("variant", ["D0", "D1", "D2"])
def test_200_resets_inside_the_regions_apart_and_the_pod_on_the_tray(variant):
    rng, regions = np.random.default_rng(1234), TASK.regions(variant)
    tray_z = CP.pod_on_tray_z(CAB, TABLE_Z)
    for _ in range(200):
        poses = TASK.sample_reset(variant, rng)
        for oid, p in poses.items():
            assert regions[oid].contains(p, obj=TASK.object(oid)), (oid, p)
        assert poses["coffee_pod"].position[2] == pytest.approx(tray_z)
        for oid in ("drawer", "coffee_machine", "mug"):
            assert poses[oid].position[2] == pytest.approx(TABLE_Z + TASK.object(oid).half_extents[2])
        yaw = {k: float(Rotation.from_quat(p.quaternion).as_euler("ZYX")[0]) for k, p in poses.items()}
        for a, b in (("drawer", "coffee_machine"), ("drawer", "mug"), ("coffee_machine", "mug")):
            assert not boxes_overlap(poses[a].position, yaw[a], TASK.object(a).half_extents, poses[b].position,
                                     yaw[b], TASK.object(b).half_extents, SEPARATION_MARGIN - 1e-9), (a, b)
        # the pod lies on the drawer's bottom, clear of its rails (+-0.064) and front / back (-0.155, 0.047)
        local = poses["drawer"].rotation.inv().apply(poses["coffee_pod"].position - poses["drawer"].position)
        local -= CAB.keypoint("body_origin")
        assert abs(local[0]) + C.POD_HALF[0] < 0.064 and -0.155 < local[1] - C.POD_HALF[0] < local[1] + C.POD_HALF[0] < 0.047
        assert not TASK.is_success(SceneState(poses, FAR, joints=initial_joint_values(TASK.objects)))


def test_bounding_circles_could_not_place_the_reference_scene():
    """Why the task keeps boxes apart: MimicGen's fixed drawer and machine are 31.6 cm apart, nearer than their
    bounding circles (robosuite checks LongDrawerObject's hand-set 0.15 m radius there)."""
    d0 = TASK.regions("D0")
    gap = np.hypot(d0["drawer"].x[0] - d0["coffee_machine"].x[0], d0["drawer"].y[0] - d0["coffee_machine"].y[0])
    assert gap == pytest.approx(0.3162, abs=1e-4) and gap < CAB.footprint_radius + M.footprint_radius
    assert boxes_overlap((0, 0), 0.0, (1, 1), (2.5, 0), 0.0, (1, 1), 0.6)
    assert not boxes_overlap((0, 0), 0.0, (1, 1), (2.5, 0), 0.0, (1, 1), 0.4)
    assert not boxes_overlap((0, 0), np.pi / 4, (1, 1), (2.5, 0), 0.0, (1, 1))   # corner 1.414: 0.086 apart
    assert boxes_overlap((0, 0), np.pi / 4, (1, 1), (2.3, 0), 0.0, (1, 1))


# ---- the pybullet world
@pytest.fixture(scope="module")
def world():
    from skillgen_ros.core.sim import SimWorld

    w = SimWorld()
    yield w
    w.close()


@pytest.mark.parametrize("variant,seed", [("D0", 0), ("D1", 3), ("D2", 0), ("D2", 5)])
def test_the_objects_build_and_settle(world, variant, seed):
    scene = world.reset("CoffeePreparation", variant, seed)
    assert scene.object_joints == {SLIDE: 0.0, LID: 0.0}
    p, body = world.p, world.bodies["drawer"]
    assert sum(len(p.getCollisionShapeData(body, k)) for k in range(-1, p.getNumJoints(body))) == 7 + 8
    assert len(p.getCollisionShapeData(world.bodies["mug"], -1)) == 16
    world.idle(40)
    now = world.object_poses()
    for oid, before in scene.poses.items():
        assert np.linalg.norm(now[oid].position - before.position) < 0.002, oid   # the pod drops its 1 mm
        assert (now[oid].rotation * before.rotation.inv()).magnitude() < np.radians(0.5), oid
    assert world.object_joints() == pytest.approx({SLIDE: 0.0, LID: 0.0}, abs=1e-4)
    assert not world.task_success()


def _move(world, target, periods: int, grip: float) -> None:
    start = world.ee_pose().position
    for k in range(1, periods + 1):
        world.step(Pose(start + (target - start) * k / periods, [1.0, 0.0, 0.0, 0.0]), grip)


def test_the_hand_opens_the_drawer_along_its_slide_within_limits(world):
    scene = world.reset("CoffeePreparation", "D0", 0)
    d, pod0 = scene.poses["drawer"], scene.poses["coffee_pod"].position
    handle = d.rotation.apply(CAB.keypoint("handle")) + d.position
    handle += d.rotation.apply([0.0, CP.HANDLE_R, 0.0])   # the bar's axis, to grasp it from above
    _move(world, handle + [0.0, 0.0, 0.10], 40, -1.0)
    _move(world, handle, 20, -1.0)
    for _ in range(10):
        world.step(Pose(handle, [1.0, 0.0, 0.0, 0.0]), 1.0)
    _move(world, handle + [0.0, 0.25, 0.0], 80, 1.0)     # the drawer's -y is the world's +y (yaw pi)
    _move(world, world.ee_pose().position, 10, -1.0)
    _move(world, world.ee_pose().position + [0.0, 0.0, 0.1], 20, -1.0)
    world.idle(20)
    v = world.object_joints()[SLIDE]
    assert CP.SLIDE_LOWER < v < CP.DRAWER_OPEN   # past MimicGen's drawer_open (-0.19), within the range
    # the tray moved along the slide: its handle by -v along the world's +y, nothing else
    moved = link_point(CAB, world.object_poses()["drawer"], {"slide": v}, "tray", "handle")
    closed = link_point(CAB, d, {"slide": 0.0}, "tray", "handle")
    assert moved - closed == pytest.approx([0.0, -v, 0.0], abs=1e-6)
    pod = world.object_poses()["coffee_pod"].position   # the pod rode along in the drawer
    assert pod[1] - pod0[1] == pytest.approx(-v, abs=0.01) and abs(pod[0] - pod0[0]) < 0.005
    assert world.object_joints()[LID] == pytest.approx(0.0, abs=1e-4)
    # beyond the upper limit (closed) the joint limit pushes it back
    world.show_state(Q_HOME, {}, {SLIDE: 0.02})
    world.idle(20)
    assert world.object_joints()[SLIDE] <= 1e-3

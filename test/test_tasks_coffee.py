"""Coffee pinned to its reference: NVlabs/mimicgen mimicgen/envs/robosuite/coffee.py (_check_lid, _check_pod,
_get_initial_placement_bounds of Coffee / Coffee_D1 / Coffee_D2, _reset_internal), .../composite_body/coffee_machine.py,
cup.py, hollow_cylinder.py and assets/objects/coffee_*.xml; region sizes from the SkillMimicGen appendix
"Tasks and Task Variants". Articulation (core/tasks/articulation.py) on hand-built values.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.robot import TABLE_CENTER_XY, TABLE_Z
from skillgen_ros.core.tasks import SceneState, get_task
from skillgen_ros.core.tasks import coffee as C
from skillgen_ros.core.tasks.articulation import Joint, Link, joint_key, link_frames, validate_articulation
from skillgen_ros.core.tasks.shapes import box, read_obj
from helpers.regions import assert_widths_match

TASK = get_task("Coffee")
M, POD = TASK.object("coffee_machine"), TASK.object("coffee_pod")
FAR = np.array([0.40, 0.0, 0.40])
SEATED_Z = -C.HOLDER_HALF_H + 2 * C.HOLDER_BASE_HALF_H + C.HOLDER_BASE_OFFSET + C.POD_HALF[2]  # on the cup base


def test_reference_geometry():
    # total_size = (body x, body y + base y, body z): the machine frame is MimicGen's root body frame
    assert M.half_extents == pytest.approx((0.0865, 0.1505, 0.1105))
    assert M.keypoint("body_origin") == pytest.approx((0.0, 0.0, 0.0))
    # coffee_machine.py locations relative to the total_size corner, worked by hand
    assert C.LID_POS == pytest.approx((0.0, 0.1045, 0.106))
    assert C.HOLDER_POS == pytest.approx((0.0, 0.1061, 0.0635))
    assert M.keypoint("pod_holder") == pytest.approx(C.HOLDER_POS)
    assert M.joints[0].origin == pytest.approx((0.0, 0.0605, 0.106))      # lid pos + (0, -lid_size[1], 0)
    assert (M.joints[0].type, M.joints[0].axis) == ("revolute", (1.0, 0.0, 0.0))
    assert (M.joints[0].lower, M.joints[0].upper) == pytest.approx((0.0, 2 * np.pi / 3))
    assert M.joints[0].initial == pytest.approx(np.radians(120.0))        # _reset_internal: 2 pi / 3
    assert M.joints[0].damping == 0.005 and M.is_fixture
    # the holder: 64 boxes with an inscribed radius of r1 cos(pi / 64), and the pod's 0.67 mm at its rim
    ring = [p for p in M.parts if p.kind == "box" and p.size[2] == C.HOLDER_HALF_H]
    assert len(ring) == 64
    inner = min(np.hypot(*(np.array(p.position[:2]) - C.HOLDER_POS[:2])) - p.size[0] for p in ring)
    assert inner == pytest.approx(0.025 * np.cos(np.pi / 64))
    assert inner - POD.half_extents[0] == pytest.approx(0.00067, abs=1e-5)
    assert POD.half_extents == pytest.approx(C.POD_HALF) and POD.mass == C.POD_MASS == 0.05
    # closed lid clears the holder's top by 5 mm; a seated pod's top clears the lid's underside
    assert (C.LID_POS[2] - C.LID_HALF[2]) - (C.HOLDER_POS[2] + C.HOLDER_HALF_H) == pytest.approx(0.005)
    assert C.HOLDER_POS[2] + SEATED_Z + C.POD_HALF[2] < C.LID_POS[2] - C.LID_HALF[2]
    # the mesh (what perception fits) shows the lid at its reset value, 120 deg open: 29.75 cm over the table
    v, _ = read_obj(M.mesh_path)
    assert v.max(0)[2] + M.half_extents[2] == pytest.approx(0.106 + 0.1105 + 0.088 * np.sin(np.radians(120))
                                                            + 0.0095 * 0.5)
    assert [s.name for s in TASK.skills] == ["grasp_pod", "insert_pod_and_close_lid"]
    assert TASK.skills[1].attached_object == "coffee_pod" and TASK.skills[1].object_id == "coffee_machine"


def _state(lid_deg: float = 0.0, dz: float = 0.0, dxy=(0.0, 0.0), yaw: float = 0.4, joints=None) -> SceneState:
    m = Pose([0.62, -0.12, TABLE_Z + M.half_extents[2]], Rotation.from_euler("z", yaw).as_quat())
    local = np.array([dxy[0], C.HOLDER_POS[1] + dxy[1], C.HOLDER_POS[2] + SEATED_Z + dz])
    pod = Pose(m.rotation.apply(local) + m.position, m.quaternion)
    js = {joint_key("coffee_machine", "lid"): np.radians(lid_deg)} if joints is None else joints
    return SceneState({"coffee_machine": m, "coffee_pod": pod}, FAR, -1.0, js)


def test_mimicgen_success_rule_on_hand_built_states():
    assert TASK.is_success(_state())
    # the pod half in the holder (raised by half its height): its top under the closed lid is impossible
    assert not TASK.is_success(_state(dz=C.POD_HALF[2]))
    # the lid 20 deg open fails; _check_lid's threshold is 15 deg
    assert not TASK.is_success(_state(lid_deg=20.0))
    assert TASK.is_success(_state(lid_deg=14.9)) and not TASK.is_success(_state(lid_deg=15.1))
    # r_diff = pod holder radius - pod radius = 5.2 mm, in any direction of the machine frame
    assert TASK.is_success(_state(dxy=(0.0051, 0.0))) and not TASK.is_success(_state(dxy=(0.0, -0.0053)))
    assert C.POD_MISS_ALLOWED == pytest.approx(0.0052, abs=5e-5)
    assert C.pod_miss([1.0, 2.0, 3.0], [1.003, 2.004, 0.0]) == pytest.approx(0.005)  # x-y only
    # the pod's bottom may not go below the holder's bottom; open lid: the pod check alone passes a high pod
    assert not TASK.is_success(_state(dz=-0.0121))
    assert C.pod_in_holder(M, POD, _state(lid_deg=120.0, dz=0.03))
    assert not C.lid_closed(M, _state(lid_deg=120.0))
    # the pod on the table beside the machine
    s = _state()
    s.poses["coffee_pod"] = Pose([0.45, 0.2, TABLE_Z + C.POD_HALF[2]], [0, 0, 0, 1])
    assert not TASK.is_success(s)


def test_missing_or_bad_joint_state_is_a_clear_error():
    for joints in ({}, {joint_key("coffee_machine", "lid"): float("nan")}):
        with pytest.raises(InvalidInputError) as e:
            TASK.is_success(_state(joints=joints))
        assert e.value.reason == "MISSING_JOINT_STATE"


def test_lid_frame_follows_the_hinge():
    m = Pose([0.5, 0.0, 0.0], [0, 0, 0, 1])
    closed = link_frames(M, m, {"lid": 0.0})["lid"]
    assert closed[:3, 3] == pytest.approx(m.position + M.joints[0].origin)
    lid0 = closed[:3, :3] @ M.links[0].keypoint("body_origin") + closed[:3, 3]
    assert lid0 == pytest.approx(m.position + C.LID_POS)
    up = link_frames(M, m, {"lid": np.pi / 2})["lid"]
    lid90 = up[:3, :3] @ M.links[0].keypoint("body_origin") + up[:3, 3]
    assert lid90 == pytest.approx(m.position + M.joints[0].origin + [0.0, 0.0, C.LID_HALF[1]])  # opening lifts it


def test_joint_and_articulation_validation():
    ok = dict(name="j", type="prismatic", child="drawer", origin=(0, 0, 0), axis=(1.0, 0.0, 0.0), lower=0.0,
              upper=0.2, initial=0.0)
    Joint(**ok)
    for bad in ({"type": "ball"}, {"axis": (1.0, 1.0, 0.0)}, {"initial": 0.3}, {"friction": -1.0}):
        with pytest.raises(InvalidInputError):
            Joint(**{**ok, **bad})
    drawer = Link("drawer", (box(0.1, 0.1, 0.02),), mass=0.5)
    validate_articulation("cabinet", (drawer,), (Joint(**ok),))
    with pytest.raises(InvalidInputError):   # a link without a joint
        validate_articulation("cabinet", (drawer, Link("knob", (box(0.01, 0.01, 0.01),), 0.01)), (Joint(**ok),))
    with pytest.raises(InvalidInputError):   # a parent declared after its child
        validate_articulation("cabinet", (drawer,), (Joint(**{**ok, "parent": "knob"}),))


PAPER = {  # SkillMimicGen appendix: (x width, y width, yaw range deg)
    ("D0", "coffee_machine"): (0.0, 0.0, 0), ("D0", "coffee_pod"): (0.06, 0.06, 0),
    ("D1", "coffee_machine"): (0.1, 0.1, 90), ("D1", "coffee_pod"): (0.25, 0.13, 0),
    ("D2", "coffee_machine"): (0.1, 0.1, 90), ("D2", "coffee_pod"): (0.25, 0.13, 0),
}


def test_region_widths_match_the_paper_to_the_millimetre():
    assert_widths_match(TASK, PAPER)


def test_region_positions_follow_mimicgen_placement_bounds():
    cx = TABLE_CENTER_XY[0]
    d0, d1, d2 = (TASK.regions(v) for v in ("D0", "D1", "D2"))
    assert d0["coffee_machine"].x == pytest.approx((cx, cx)) and d0["coffee_machine"].y == pytest.approx((-0.1, -0.1))
    assert np.degrees(d0["coffee_machine"].yaw) == pytest.approx((-30.0, -30.0))
    assert d0["coffee_pod"].x == pytest.approx((cx - 0.13, cx - 0.07)) and d0["coffee_pod"].y == pytest.approx((0.17, 0.23))
    assert d1["coffee_machine"].x == pytest.approx((cx + 0.05, cx + 0.15))
    assert np.degrees(d1["coffee_machine"].yaw) == pytest.approx((-30.0, 60.0))
    assert d2["coffee_machine"].y == pytest.approx((0.1, 0.2)) and d2["coffee_pod"].y == pytest.approx((-0.3, -0.17))
    assert np.degrees(d2["coffee_machine"].yaw) == pytest.approx((120.0, 210.0))
    rng = np.random.default_rng(5)
    for v in ("D0", "D1", "D2"):
        for _ in range(30):
            poses = TASK.sample_reset(v, rng)
            assert all(TASK.regions(v)[k].contains(p, obj=TASK.object(k)) for k, p in poses.items())
            assert poses["coffee_machine"].position[2] == pytest.approx(TABLE_Z + 0.1105)


def test_the_deploy_goal_of_the_insertion_reads_the_lid():
    """HSP deployment's early goal check (core/deploy/goals.py) on the insert-and-close skill: met with the pod
    seated and the lid shut, not with the lid open, and not known (so not met) without a lid value."""
    from skillgen_ros.core.deploy.goals import skill_goal_reached

    skill = TASK.skills[1]
    lid = joint_key("coffee_machine", "lid")

    def reached(joints):
        s = _state()
        return skill_goal_reached(TASK, skill, s.poses, np.r_[FAR, 0, 0, 0, 1], 0.08, -1.0, joints)
    assert reached({lid: 0.0})
    assert not reached({lid: np.radians(20.0)})
    assert not reached(None) and not reached({})


def test_clutter_variants_add_the_obstruction_between_robot_and_machine():
    """The paper's Coffee (D0, Clutter) / (D1, Clutter) (its clutter table): the base variant's regions plus the
    obstruction; box footprints keep it off the machine, and leave the D0-D2 resets as circles would."""
    from dataclasses import replace

    from skillgen_ros.core.tasks.suite import COFFEE_OBSTACLE_REGION
    assert TASK.variants == ("D0", "D1", "D2", "D0_clutter", "D1_clutter") and TASK.footprint == "box"
    circles = replace(TASK, footprint="circle")
    for v in ("D0", "D1", "D2"):
        for seed in range(40):
            a, b = TASK.sample_reset(v, np.random.default_rng(seed)), circles.sample_reset(v, np.random.default_rng(seed))
            assert all(np.allclose(a[k].position, b[k].position) for k in a), (v, seed)
    holder = M.keypoint("pod_holder")
    for v in ("D0_clutter", "D1_clutter"):
        base = TASK.regions(v[:2])
        assert [o.id for o in TASK.objects_for(v)] == ["coffee_machine", "coffee_pod", "obstacle"]
        assert {k: r for k, r in TASK.regions(v).items() if k != "obstacle"} == base
        assert TASK.regions(v)["obstacle"] == COFFEE_OBSTACLE_REGION
        rng = np.random.default_rng(3)
        for _ in range(30):
            poses = TASK.sample_reset(v, rng)
            m, pod, obs = (poses[k] for k in ("coffee_machine", "coffee_pod", "obstacle"))
            assert all(TASK.regions(v)[k].contains(p, obj=TASK.object(k)) for k, p in poses.items())
            for k in ("coffee_machine", "coffee_pod"):   # apart by oriented boxes
                assert TASK._apart(TASK.object("obstacle"), *obs.position[:2],
                                   float(Rotation.from_quat(obs.quaternion).as_euler("ZYX")[0]),
                                   TASK.object(k), poses[k])
            # between the robot (x < 0 in the world) and the holder
            h = m.position[:2] + Rotation.from_quat(m.quaternion).apply(holder)[:2]
            assert obs.position[0] < h[0] and np.linalg.norm(obs.position[:2] - pod.position[:2]) > 0.1

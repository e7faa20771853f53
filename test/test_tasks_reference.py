"""The task geometry, success rules and reset regions pinned to their references.

robosuite 1.5.2 (environments/manipulation/nut_assembly.py, models/assets/objects/*-nut.xml,
models/assets/arenas/pegs_arena.xml, the Panda's table mounting), NVlabs/mimicgen
(mimicgen/envs/robosuite/{nut_assembly,threading}.py, models/robosuite/objects/composite/
{needle,ring_tripod}.py) and the SkillMimicGen appendix "Tasks and Task Variants".
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.robot import TABLE_CENTER_XY, TABLE_FULL_SIZE, TABLE_Z
from skillgen_ros.core.tasks import SceneState, get_task
from skillgen_ros.core.tasks import objects as O
from skillgen_ros.core.tasks import suite as S
from helpers.regions import assert_widths_match

FAR = np.array([0.40, 0.0, 0.40])  # an EE position well away from every object


def _yaw(a: float) -> np.ndarray:
    return Rotation.from_euler("z", a).as_quat()


def test_robosuite_mounting():
    # base_xpos_offset["table"](0.8) = (-0.56, 0, 0); base z 0.912 (RethinkMount); NutAssembly table top 0.82
    assert TABLE_CENTER_XY == pytest.approx((0.56, 0.0))
    assert TABLE_Z == pytest.approx(0.82 - 0.912)
    assert TABLE_FULL_SIZE == pytest.approx((0.8, 0.8, 0.05))


def test_reference_dimensions():
    assert O.PEG_HEIGHT == pytest.approx(0.13)                       # 0.85 + 0.1 - 0.82
    assert O.square_peg().half_extents == pytest.approx((0.016, 0.016, 0.065))
    assert O.round_peg().half_extents == pytest.approx((0.02, 0.02, 0.065))
    assert 2 * O.SQUARE_HOLE_HALF == pytest.approx(0.046)             # robosuite 4.55 cm, kept
    assert 2 * O.ROUND_HOLE_RADIUS == pytest.approx(0.0624)           # octagon, inscribed
    rn = O.round_nut()
    walls = [p for p in rn.parts if np.allclose(p.size, (0.01125, 0.0225, 0.01))]
    assert len(walls) == 8
    centre = rn.keypoint("ring_center")
    inner = [np.linalg.norm(np.asarray(p.position)[:2] - centre[:2]) - 0.01125 for p in walls]
    assert inner == pytest.approx([0.0312] * 8)
    # needle: 1 x 1 x 12 cm shaft on a 4 cm cube handle; tripod: 1.6 cm square hole, 1.2 cm success radius
    nd = O.needle()
    assert nd.half_extents == pytest.approx((0.08, 0.02, 0.02))
    shaft = [p for p in nd.parts if np.allclose(p.size, (0.06, 0.005, 0.005))]
    assert len(shaft) == 1
    assert np.linalg.norm(nd.keypoint("tip") - nd.keypoint("shaft_base")) == pytest.approx(0.12)
    assert 2 * O.RING_OPENING_HALF == pytest.approx(0.016) and O.RING_SIZE[1] == pytest.approx(0.012)
    assert O.RING_OPENING_HALF - O.NEEDLE_SHAFT_HALF == pytest.approx(0.003)   # 3 mm a side
    tp = O.tripod()
    rest_z = TABLE_Z + tp.half_extents[2]
    assert rest_z + tp.keypoint("ring_center")[2] - TABLE_Z == pytest.approx(0.188, abs=0.001)


def test_threshold_constants():
    assert S.ON_PEG_XY == 0.03 and S.ON_PEG_Z == 0.05 and S.R_REACH_MAX == 0.6
    assert S.RELEASE_DISTANCE == pytest.approx(np.arctanh(0.4) / 10) and 0.042 < S.RELEASE_DISTANCE < 0.0425


def _nut_at(nut, ring_xyz, yaw=0.0) -> Pose:
    R = Rotation.from_euler("z", yaw)
    return Pose(np.asarray(ring_xyz, float) - R.apply(nut.keypoint("ring_center")), R.as_quat())


def _peg_at(peg, x, y) -> Pose:
    return Pose([x, y, TABLE_Z + peg.half_extents[2]], _yaw(0.0))


@pytest.mark.parametrize("task,nut_id,peg_id", [("Square", "square_nut", "square_peg"),
                                                ("NutAssembly", "round_nut", "round_peg")])
def test_robosuite_on_peg_cases(task, nut_id, peg_id):
    spec = get_task(task)
    nut, peg = spec.object(nut_id), spec.object(peg_id)
    peg_pose = _peg_at(peg, 0.70, 0.05)
    rest = TABLE_Z + nut.half_extents[2]

    def ok(ring_xyz, ee=FAR) -> bool:
        return S.nut_on_peg(nut, peg, SceneState({nut_id: _nut_at(nut, ring_xyz, 0.4), peg_id: peg_pose}, ee))

    assert ok([0.70, 0.05, rest])                                   # resting on the table around the peg
    assert ok([0.70 + 0.029, 0.05 - 0.029, rest])                   # |dx|, |dy| < 3 cm
    assert not ok([0.70 + 0.031, 0.05, rest]) and not ok([0.70, 0.05 - 0.031, rest])
    assert ok([0.70, 0.05, TABLE_Z + 0.0499]) and not ok([0.70, 0.05, TABLE_Z + 0.0501])
    # a nut resting 1 cm onto the top of its 13 cm peg is not on it
    assert not ok([0.70, 0.05, TABLE_Z + O.PEG_HEIGHT - 0.01])


def test_released_hand_condition():
    spec = get_task("Square")
    nut, peg = spec.object("square_nut"), spec.object("square_peg")
    ring = np.array([0.70, 0.05, TABLE_Z + nut.half_extents[2]])
    poses = {"square_nut": _nut_at(nut, ring), "square_peg": _peg_at(peg, 0.70, 0.05)}
    d = S.RELEASE_DISTANCE
    assert spec.is_success(SceneState(poses, ring + [0.0, 0.0, d + 0.001]))      # hand moved off
    assert not spec.is_success(SceneState(poses, ring + [0.0, 0.0, d - 0.001]))  # hand still at the nut
    assert not spec.is_success(SceneState(poses, ring + [0.02, 0.0, 0.0]))


def test_nut_assembly_needs_both_nuts():
    spec = get_task("NutAssembly")
    sn, rn, sp, rp = (spec.object(k) for k in ("square_nut", "round_nut", "square_peg", "round_peg"))
    z = TABLE_Z + 0.01
    poses = {"square_peg": _peg_at(sp, 0.79, 0.1), "round_peg": _peg_at(rp, 0.79, -0.1),
             "square_nut": _nut_at(sn, [0.79, 0.1, z]), "round_nut": _nut_at(rn, [0.79, -0.1, z])}
    assert spec.is_success(SceneState(poses, FAR))
    poses["round_nut"] = _nut_at(rn, [0.45, -0.1, z])
    assert not spec.is_success(SceneState(poses, FAR))


def test_mimicgen_threading_rule():
    spec = get_task("Threading")
    nd, tp = spec.object("needle"), spec.object("tripod")
    tripod = Pose([0.56, -0.15, TABLE_Z + tp.half_extents[2]], _yaw(np.pi / 2))   # ring axis = world +y
    ring = tripod.rotation.apply(tp.keypoint("ring_center")) + tripod.position
    R = Rotation.from_euler("z", np.pi / 2)

    def needle_with_shaft_centre_at(p) -> Pose:
        return Pose(np.asarray(p) - R.apply(nd.keypoint("shaft_center")), R.as_quat())

    def ok(p) -> bool:
        return spec.is_success(SceneState({"needle": needle_with_shaft_centre_at(p), "tripod": tripod}, FAR))

    axis = R.apply([1.0, 0.0, 0.0])
    assert ok(ring) and ok(ring + axis * 0.0119) and ok(ring + [0.0, 0.0, 0.0119])
    assert not ok(ring + axis * 0.0121) and not ok(ring - axis * 0.0121)
    assert not ok(ring - axis * 0.04)   # tip 2 cm through the ring (shaft centre 4 cm short): not enough
    assert not ok(ring + [0.0, 0.0, 0.0121])


# The paper's appendix "Tasks and Task Variants": region sizes (x, y) in m and yaw spans in degrees.
PAPER = {
    ("Square", "D0", "square_nut"): (0.005, 0.115, 360), ("Square", "D0", "square_peg"): (0.0, 0.0, 0),
    ("Square", "D1", "square_peg"): (0.4, 0.4, 0), ("Square", "D1", "square_nut"): (0.23, 0.51, 360),
    ("Square", "D2", "square_peg"): (0.5, 0.5, 90), ("Square", "D2", "square_nut"): (0.5, 0.5, 360),
    ("NutAssembly", "D0", "square_nut"): (0.005, 0.115, 360), ("NutAssembly", "D0", "round_nut"): (0.005, 0.115, 360),
    ("NutAssembly", "D0", "square_peg"): (0.0, 0.0, 0), ("NutAssembly", "D0", "round_peg"): (0.0, 0.0, 0),
    ("NutAssembly", "D1", "square_nut"): (0.23, 0.51, 360), ("NutAssembly", "D1", "round_nut"): (0.23, 0.51, 360),
    ("NutAssembly", "D1", "square_peg"): (0.4, 0.4, 0), ("NutAssembly", "D1", "round_peg"): (0.4, 0.4, 0),
    ("NutAssembly", "D2", "square_nut"): (0.5, 0.5, 360), ("NutAssembly", "D2", "round_nut"): (0.5, 0.5, 360),
    ("NutAssembly", "D2", "square_peg"): (0.5, 0.5, 90), ("NutAssembly", "D2", "round_peg"): (0.5, 0.5, 90),
    ("Threading", "D0", "needle"): (0.15, 0.1, 60), ("Threading", "D0", "tripod"): (0.0, 0.0, 0),
    ("Threading", "D1", "needle"): (0.25, 0.1, 240), ("Threading", "D1", "tripod"): (0.25, 0.1, 120),
    ("Threading", "D2", "needle"): (0.25, 0.1, 240), ("Threading", "D2", "tripod"): (0.25, 0.1, 120),
}


def test_every_paper_region_width_to_the_millimetre():
    for task in ("Square", "NutAssembly", "Threading"):
        spec = get_task(task)
        # every region of every variant (D1_clutter: the D1 regions plus the obstacle, not the paper's)
        assert_widths_match(spec, {(v, oid): PAPER[(task, v.split("_")[0], oid)] for v in spec.variants
                                   for oid in spec.regions(v) if oid != "obstacle"})


def test_region_positions_follow_mimicgen_placement_initializers():
    cx = TABLE_CENTER_XY[0]
    sq = get_task("Square")
    assert sq.regions("D0")["square_peg"].x == pytest.approx((cx + 0.23, cx + 0.23))   # pegs_arena.xml peg1
    assert sq.regions("D0")["square_nut"].x == pytest.approx((cx - 0.115, cx - 0.11))
    assert sq.regions("D1")["square_peg"].x == pytest.approx((cx - 0.1, cx + 0.3))
    assert sq.regions("D1")["square_nut"].y == pytest.approx((-0.255, 0.255))
    th = get_task("Threading")
    assert th.regions("D0")["tripod"].y == pytest.approx((-0.15, -0.15))
    assert np.degrees(th.regions("D0")["needle"].yaw) == pytest.approx((-210.0, -150.0))  # MimicGen -120..-60
    assert th.regions("D2")["tripod"].y == pytest.approx((0.1, 0.2))
    assert np.degrees(th.regions("D2")["tripod"].yaw) == pytest.approx((-150.0, -30.0))


def test_regions_hold_the_reference_body_origin():
    """A nut's region holds its ring centre (robosuite's nut body), not our bounding-box centre."""
    sq = get_task("Square")
    nut = sq.object("square_nut")
    r = sq.regions("D0")["square_nut"]
    rng = np.random.default_rng(3)
    for _ in range(50):
        p = sq.sample_reset("D0", rng)["square_nut"]
        ring = p.rotation.apply(nut.keypoint("ring_center")) + p.position
        assert r.x[0] - 1e-9 <= ring[0] <= r.x[1] + 1e-9 and r.y[0] - 1e-9 <= ring[1] <= r.y[1] + 1e-9

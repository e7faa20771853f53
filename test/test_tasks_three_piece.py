"""Three Piece Assembly pinned to its reference: NVlabs/mimicgen mimicgen/envs/robosuite/three_piece_assembly.py
(patterns, unit sizes, densities, _check_*_piece_is_assembled, _get_initial_placement_bounds),
models/robosuite/objects/composite/box_pattern_object.py, and the SkillMimicGen appendix "Tasks and Task Variants".
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.robot import TABLE_CENTER_XY, TABLE_Z
from skillgen_ros.core.tasks import SceneState, get_task
from skillgen_ros.core.tasks import assembly as A
from helpers.regions import assert_widths_match

FAR = np.array([0.40, 0.0, 0.40])
TASK = get_task("ThreePieceAssembly")


def _q(yaw: float) -> np.ndarray:
    return Rotation.from_euler("z", yaw).as_quat()


def _cells(spec) -> float:
    return sum(8 * float(np.prod(p.size)) for p in spec.parts)


def test_reference_geometry():
    b, p1, p2 = TASK.object("base"), TASK.object("piece_1"), TASK.object("piece_2")
    # base: 5 x 5 cubes of 3.8 cm with the centre 3 x 3 empty (16 cubes), 3.8 cm thick
    assert b.half_extents == pytest.approx((0.095, 0.095, 0.019))
    assert _cells(b) == pytest.approx(16 * 0.038 ** 3)
    assert 2 * A.BASE_HOLE_HALF == pytest.approx(0.114)
    # piece 1: a 3 x 3 layer plus a 1 x 3 ridge two cubes tall, 3.4 cm cubes (15 cubes)
    assert p1.half_extents == pytest.approx((0.051, 0.051, 0.051))
    assert _cells(p1) == pytest.approx(15 * 0.034 ** 3)
    # piece 2: 2 layers of 6 cubes (the slot), a full layer, the knob: 22 cubes of 4 cm, 16 cm tall
    assert p2.half_extents == pytest.approx((0.06, 0.06, 0.08))
    assert _cells(p2) == pytest.approx(22 * 0.04 ** 3)
    # clearances: piece 1's 10.2 cm plate in the 11.4 cm hole, its 3.4 cm ridge in piece 2's 4 cm slot
    assert A.BASE_HOLE_HALF - A.PIECE_1_HALF == pytest.approx(0.006)
    assert A.SLOT_HALF - A.RIDGE_HALF == pytest.approx(0.003)
    # masses from MimicGen's densities (base 10000, pieces 100 kg/m^3); all three are free bodies
    assert b.mass == pytest.approx(10000 * 16 * 0.038 ** 3) and p2.mass == pytest.approx(100 * 22 * 0.04 ** 3)
    assert not any(o.is_fixture for o in TASK.objects)
    assert (b.symmetry, p1.symmetry, p2.symmetry) == ("z4", "z2", "z2")
    assert [s.name for s in TASK.skills] == ["grasp_piece_1", "insert_piece_1_into_base", "grasp_piece_2",
                                             "insert_piece_2_into_piece_1"]


def _assembled_poses(dz2: float = 0.0, dxy2=(0.0, 0.0), dxy1=(0.0, 0.0)) -> dict[str, Pose]:
    """The stack as it settles: piece 1 on the table in the hole, piece 2's legs on the base's top."""
    b, p1, p2 = TASK.object("base"), TASK.object("piece_1"), TASK.object("piece_2")
    c = np.array([0.6, -0.05])
    return {"base": Pose([*c, TABLE_Z + b.half_extents[2]], _q(0.3)),
            "piece_1": Pose([*(c + dxy1), TABLE_Z + p1.half_extents[2]], _q(0.3 + np.pi / 2)),
            "piece_2": Pose([*(c + dxy2), TABLE_Z + 2 * b.half_extents[2] + p2.half_extents[2] + dz2],
                            _q(0.3 + np.pi / 2))}


def test_mimicgen_success_rule_on_hand_built_states():
    ok = lambda poses, ee=FAR, g=-1.0: TASK.is_success(SceneState(poses, ee, g))  # noqa: E731
    assert ok(_assembled_poses())
    # the settled stack: piece 2 sits 1.9 cm above base z + 8 cm (z_correct), inside the 2 cm threshold
    assert ok(_assembled_poses(dz2=0.0009)) and not ok(_assembled_poses(dz2=0.0011))
    assert not ok(_assembled_poses(dz2=-0.0391 - 0.001))   # 2 cm below z_correct
    # x-y thresholds: piece 1 within 2 cm of the base, piece 2 within 2 cm of piece 1
    assert ok(_assembled_poses(dxy2=(0.0141, 0.0141))) and not ok(_assembled_poses(dxy2=(0.0142, 0.0142)))
    assert not ok(_assembled_poses(dxy1=(0.021, 0.0), dxy2=(0.021, 0.0)))
    # piece 2 beside the stack on the table: not assembled
    poses = _assembled_poses()
    poses["piece_2"] = Pose([0.40, 0.2, TABLE_Z + 0.08], _q(0.0))
    assert not ok(poses)
    # still held: the gripper closed with the grasp point at piece 2's knob (or piece 1's ridge) fails;
    # the same hand open, or closed but away from the piece, passes
    poses = _assembled_poses()
    knob = poses["piece_2"].position + [0.0, 0.0, 0.06]
    assert not ok(poses, knob, 1.0) and ok(poses, knob, -1.0) and ok(poses, knob + [0, 0, 0.04], 1.0)


def test_first_piece_rule():
    b, p1 = TASK.object("base"), TASK.object("piece_1")
    poses = _assembled_poses()
    assert A.first_piece_assembled(b, p1, SceneState(poses, FAR))
    ridge = poses["piece_1"].position + [0.0, 0.0, 0.03]
    assert not A.first_piece_assembled(b, p1, SceneState(poses, ridge, 1.0))
    poses["piece_1"] = Pose(poses["base"].position + [0.0, 0.0201, 0.03], _q(0.0))
    assert not A.first_piece_assembled(b, p1, SceneState(poses, FAR))


# The paper's appendix: (x width, y width, yaw span in degrees); MimicGen's bounds give the same.
PAPER = {("D0", "base"): (0.0, 0.0, 0), ("D0", "piece_1"): (0.44, 0.44, 0), ("D0", "piece_2"): (0.44, 0.44, 0),
         ("D1", "base"): (0.44, 0.44, 0), ("D1", "piece_1"): (0.44, 0.44, 0), ("D1", "piece_2"): (0.44, 0.44, 0),
         ("D2", "base"): (0.44, 0.44, 90), ("D2", "piece_1"): (0.44, 0.44, 180),
         ("D2", "piece_2"): (0.44, 0.44, 180)}


def test_regions_to_the_millimetre():
    assert TASK.variants == ("D0", "D1", "D2")
    for v in TASK.variants:
        assert list(TASK.regions(v)) == ["base", "piece_1", "piece_2"]   # MimicGen's sampling order
    assert_widths_match(TASK, PAPER)
    cx, cy = TABLE_CENTER_XY
    assert TASK.regions("D0")["base"].x == pytest.approx((cx, cx)) and TASK.regions("D0")["base"].y == (cy, cy)
    assert TASK.regions("D0")["piece_1"].x == pytest.approx((cx - 0.22, cx + 0.22))
    assert np.degrees(TASK.regions("D0")["piece_2"].yaw) == pytest.approx((90.0, 90.0))   # z_rot 1.5708
    assert np.degrees(TASK.regions("D2")["base"].yaw) == pytest.approx((-45.0, 45.0))
    assert np.degrees(TASK.regions("D2")["piece_1"].yaw) == pytest.approx((0.0, 180.0))


def test_the_seated_stack_settles_assembled_in_the_sim():
    """pybullet: piece 1 dropped into the hole and piece 2 onto its ridge settle where the rule wants them."""
    from skillgen_ros.core.sim.world import SimWorld

    w = SimWorld()
    try:
        w.reset("ThreePieceAssembly", "D0", 3)
        b = w.object_poses()["base"].position
        w._set_object_pose("piece_1", Pose([b[0] + 0.003, b[1], TABLE_Z + 0.051 + 0.005], _q(np.pi / 2)))
        w._set_object_pose("piece_2", Pose([b[0] + 0.001, b[1], TABLE_Z + 0.118 + 0.01], _q(np.pi / 2)))
        assert not w.task_success()   # piece 2 still 1 cm up, over the threshold
        w.idle(40)
        p = w.object_poses()
        assert p["piece_2"].position[2] - p["base"].position[2] == pytest.approx(0.099, abs=0.001)
        assert w.task_success()
    finally:
        w.close()

"""Task suite (pure): registry, object specs and meshes, reset regions, success predicates."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skillgen_ros.core.errors import InvalidInputError, UnknownTaskError, UnknownVariantError
from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.robot import TABLE_Z
from skillgen_ros.core.tasks import TASK_NAMES, SceneState, get_task, regions_markdown, validate_seed
from skillgen_ros.core.tasks import objects as O
from skillgen_ros.core.tasks.articulation import initial_joint_values, posed_link_parts
from skillgen_ros.core.tasks.shapes import aabb, read_obj
from skillgen_ros.core.tasks.spec import SEPARATION_MARGIN

CASES = [(t, v) for t in TASK_NAMES for v in get_task(t).variants]


def test_registry_and_skills():
    assert {t: len(get_task(t).skills) for t in TASK_NAMES} == {"Square": 2, "PickPlace": 2, "NutAssembly": 4,
                                                                 "Threading": 2, "ThreePieceAssembly": 4,
                                                                 "Coffee": 2, "CoffeePreparation": 5}
    assert get_task("Square").variants == ("D0", "D1", "D2", "D1_clutter", "D2_clutter")  # the paper's
    assert "clutter" in get_task("PickPlace").variants  # ours (PickPlace is not a paper task)
    assert not any("clutter" in v for v in get_task("Threading").variants + get_task("NutAssembly").variants)
    with pytest.raises(UnknownTaskError) as e:
        get_task("MugCleanup")   # a MimicGen task we do not build
    assert e.value.reason == "UNKNOWN_TASK"
    with pytest.raises(UnknownVariantError):
        get_task("Square").sample_reset("D7", np.random.default_rng(0))
    for t in TASK_NAMES:
        spec = get_task(t)
        ids = {o.id for o in spec.objects}
        for s in spec.skills:
            assert s.object_id in ids and s.mode in ("transit", "transfer")
            assert (s.mode == "transfer") == (s.attached_object is not None)
    for v in ("D1_clutter", "D2_clutter"):
        assert [o.id for o in get_task("Square").objects_for(v)][-1] == "obstacle"
        assert get_task("Square").regions(v)["square_peg"] == get_task("Square").regions(v[:2])["square_peg"]
    assert "obstacle" not in {o.id for o in get_task("Square").objects_for("D1")}


@pytest.mark.parametrize("name", TASK_NAMES)
def test_meshes_match_specs(name):
    spec = get_task(name)
    for o in spec.objects + ((spec.obstacle,) if spec.obstacle else ()):
        v, f = read_obj(o.mesh_path)
        assert len(f) > 0 and f.max() < len(v)
        if o.joints:  # the mesh shows the links at their reset values too; half_extents: the fixed base only
            lo, hi = aabb(o.parts + posed_link_parts(o.links, o.joints))
            np.testing.assert_allclose(v.min(0), lo, atol=1e-4)
            np.testing.assert_allclose(v.max(0), hi, atol=1e-4)
            lo, hi = aabb(o.parts)
            np.testing.assert_allclose((hi - lo) / 2, o.half_extents, atol=1e-9)
            np.testing.assert_allclose((hi + lo) / 2, 0.0, atol=1e-9)  # origin = the base's bbox centre
            continue
        np.testing.assert_allclose((v.max(0) - v.min(0)) / 2, o.half_extents, atol=1e-4)
        np.testing.assert_allclose((v.max(0) + v.min(0)) / 2, 0.0, atol=1e-4)  # origin = bbox centre
        assert o.symmetry in ("none", "z2", "z4", "z_continuous")
        assert (o.mass == 0) == o.is_fixture


# Coffee Prep's pod starts in its drawer, not on the table: test_tasks_coffee_prep has its own reset test
@pytest.mark.parametrize("task,variant", [c for c in CASES if c[0] != "CoffeePreparation"])
def test_200_resets_inside_documented_regions(task, variant):
    spec = get_task(task)
    regions = spec.regions(variant)
    rng = np.random.default_rng(1234)
    for _ in range(200):
        poses = spec.sample_reset(variant, rng)
        assert set(poses) == {o.id for o in spec.objects_for(variant)}
        for oid, p in poses.items():
            assert regions[oid].contains(p, obj=spec.object(oid)), (oid, p)
            assert p.position[2] == pytest.approx(TABLE_Z + spec.object(oid).half_extents[2])
        items = list(poses.items())
        for i, (a, pa) in enumerate(items):
            for b, pb in items[i + 1:]:
                if spec.footprint == "box":   # oriented x-y boxes (Coffee)
                    yaw_b = float(Rotation.from_quat(pb.quaternion).as_euler("ZYX")[0])
                    assert spec._apart(spec.object(a), pa.position[0], pa.position[1],
                                       float(Rotation.from_quat(pa.quaternion).as_euler("ZYX")[0]),
                                       spec.object(b), pb), (a, b, yaw_b)
                    continue
                gap = np.hypot(*(pa.position[:2] - pb.position[:2]))
                assert gap >= spec.object(a).footprint_radius + spec.object(b).footprint_radius + SEPARATION_MARGIN - 1e-9
        reset_joints = initial_joint_values(spec.objects_for(variant))  # Coffee's lid open, as a reset leaves it
        assert not spec.is_success(SceneState(poses, np.array([0.46, 0.0, 0.3]), joints=reset_joints))


def test_same_seed_same_reset_and_region_table_documented():
    spec = get_task("NutAssembly")
    a = spec.sample_reset("D2", np.random.default_rng(7))
    b = spec.sample_reset("D2", np.random.default_rng(7))
    assert all(np.array_equal(a[k].as_array(), b[k].as_array()) for k in a)
    table = regions_markdown()
    for t, v in CASES:
        assert f"| {t} | {v} |" in table
    with open("docs/tasks.md") as f:
        assert table in f.read(), "docs/tasks.md is stale: regenerate it from regions_markdown()"


def test_seed_validation():
    assert validate_seed(0) == 0 and validate_seed(2**32 - 1) == 2**32 - 1
    for bad in (-1, 2**32, 2**63, 1.5, "3", True):
        with pytest.raises(InvalidInputError) as e:
            validate_seed(bad)
        assert e.value.reason == "INVALID_SEED"


def _yaw(yaw):
    return Rotation.from_euler("z", yaw).as_quat()


def test_pick_place_success_on_constructed_poses():
    pp = get_task("PickPlace")
    bin_ = Pose([0.55, 0.2, 0.03], _yaw(0.3))
    far = np.array([0.4, 0.0, 0.4])
    assert pp.is_success(SceneState({"milk": Pose([0.56, 0.21, 0.065], _yaw(0.0)), "bin": bin_}, far))
    assert not pp.is_success(SceneState({"milk": Pose([0.56, -0.1, 0.055], _yaw(0.0)), "bin": bin_}, far))
    assert not pp.is_success(SceneState({"milk": Pose([0.56, 0.21, 0.30], _yaw(0.0)), "bin": bin_}, far))
    with pytest.raises(InvalidInputError):
        pp.is_success({"milk": bin_, "bin": bin_})  # a bare pose map: the rule needs the EE too


def test_object_lookup_errors():
    with pytest.raises(InvalidInputError):
        get_task("Square").object("nope")
    with pytest.raises(InvalidInputError):
        O.milk().keypoint("handle")

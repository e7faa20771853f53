"""bench/datagen/contact_model.py: the pad model loads as robosuite's pads, and the in-hand turn is measured."""
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation as R


def test_pads_urdf_adds_one_box_per_finger_and_drops_the_soft_contact():
    import pybullet as pb
    from pathlib import Path

    from bench.datagen import contact_model
    from skillgen_ros.core.sim.assets import lowpoly_panda_urdf

    stock = Path(lowpoly_panda_urdf()).read_text()
    text = contact_model.pads_urdf(stock)
    assert stock.count("<box") == 0 and text.count('<box size="0.016 0.008 0.016"/>') == 2
    assert stock.count("<stiffness") == 2 and text.count("<stiffness") == 0
    path = Path(lowpoly_panda_urdf()).with_name("test_panda_pads.urdf")
    path.write_text(text)
    cid = pb.connect(pb.DIRECT)
    try:
        robot = pb.loadURDF(str(path), useFixedBase=True, physicsClientId=cid)
        links = {pb.getJointInfo(robot, i, physicsClientId=cid)[12].decode(): i
                 for i in range(pb.getNumJoints(robot, physicsClientId=cid))}
        for name, side in (("panda_leftfinger", 1), ("panda_rightfinger", -1)):
            shapes = pb.getCollisionShapeData(robot, links[name], physicsClientId=cid)
            boxes = [s for s in shapes if s[2] == pb.GEOM_BOX]
            assert len(shapes) == 2 and len(boxes) == 1  # the finger mesh and its pad
            assert boxes[0][3] == pytest.approx((0.016, 0.008, 0.016))
            inertial = np.array(pb.getDynamicsInfo(robot, links[name], physicsClientId=cid)[3])
            # shape data are in the link's inertial frame: the pad sits 0.0035 toward the finger's back, 4.3 cm up
            assert np.add(boxes[0][5], inertial) == pytest.approx((0.0, side * 0.0035, 0.043))
    finally:
        pb.disconnect(cid)
        path.unlink()


def test_turned_in_hand_measures_the_transfer_and_the_skill_separately():
    from bench.datagen.contact_model import turned_in_hand

    n = 6
    hand = R.from_euler("z", np.linspace(0, 90, n)[:, None], degrees=True)  # the hand turns; a held object turns with it
    in_hand = R.from_euler("y", np.array([0, 0, 0, 10, 10, 25.0])[:, None], degrees=True)  # ... and in it: 10 deg, then 15 more
    obj = hand * in_hand
    ep = SimpleNamespace(labels={"skill_index": np.array([0, 0, 1, 1, 1, 1]), "mp_step": np.array([0, 0, 1, 0, 0, 0])},
                         obs={"robot0_eef_quat": hand.as_quat(), "needle_pose": np.c_[np.zeros((n, 3)), obj.as_quat()]})
    transfer, skill = turned_in_hand(ep, "needle", 0)
    assert transfer == pytest.approx(10.0) and skill == pytest.approx(15.0)
    ep.labels["skill_index"] = np.zeros(n, int)
    assert turned_in_hand(ep, "needle", 0) is None  # never reached the next skill


def test_use_model_patches_the_named_part_and_stock_restores_the_sim():
    from bench.datagen import contact_model
    from skillgen_ros.core.sim import assets, world

    stock_spawn, stock_init = world.SimWorld._spawn, world.SimWorld.__init__
    try:
        contact_model.use_model("hz:480+iterations:100")
        w = world.SimWorld()
        assert (w.cfg.physics_hz, w.cfg.solver_iterations, w.substeps) == (480.0, 100, 24)
        w.close()
        contact_model.use_model("mass:needle:10")
        assert world.SimWorld._spawn is not stock_spawn
        contact_model.use_model("pads")
        assert world.SimWorld._spawn is stock_spawn and world.lowpoly_panda_urdf() != assets.lowpoly_panda_urdf()
        for bad in ("softer", "ring:soft", "mass:needle", "mass:needle:-1", "ring:0", "pads:2", "mass::3", "pads+", "hz:250", "iterations:x"):
            with pytest.raises(SystemExit, match="unknown arm"):
                contact_model.use_model(bad)
    finally:
        contact_model.use_model("stock")
    assert world.SimWorld._spawn is stock_spawn and world.lowpoly_panda_urdf is assets.lowpoly_panda_urdf
    assert world.SimWorld.__init__ is stock_init


def test_an_arm_for_an_object_the_task_lacks_is_refused_before_any_attempt():
    from bench.datagen import contact_model

    assert contact_model.parse_arm("mass:needle:10") == [("mass", "needle", 10.0)]
    assert contact_model.parse_arm("pads+ring:300") == [("pads", "", 0.0), ("ring", "tripod", 300.0)]
    with pytest.raises(SystemExit, match="Square has no object 'tripod'"):
        contact_model.run_arm("ring:300", "Square", "D0", [1000], 1, 0.05)

"""core/sim/contact_model.py: the named contact models, robosuite's finger pads, and their validation."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.sim.assets import lowpoly_panda_urdf
from skillgen_ros.core.sim.contact_model import (CONTACT_MODELS, DEFAULT_CONTACT_MODEL, contact_settings,
                                                 pads_urdf)


def test_pads_urdf_adds_one_box_per_finger_and_drops_the_soft_contact():
    stock = Path(lowpoly_panda_urdf()).read_text()
    text = pads_urdf(stock)
    # robosuite panda_gripper.xml finger1_pad_collision: half size 0.008 0.004 0.008
    assert stock.count("<box") == 0 and text.count('<box size="0.016 0.008 0.016"/>') == 2
    assert stock.count("<stiffness") == 2 and text.count("<stiffness") == 0
    assert text.count("<link ") == stock.count("<link ")


def test_a_pads_world_loads_the_pad_beside_each_finger_mesh():
    from skillgen_ros.core.sim import SimWorld

    w = SimWorld(**contact_settings("robosuite_pads"))
    try:
        assert w.cfg.finger_pads and w.cfg.solver_iterations == 200
        p = w.p
        links = {p.getJointInfo(w.robot, i)[12].decode(): i for i in range(p.getNumJoints(w.robot))}
        for name, side in (("panda_leftfinger", 1), ("panda_rightfinger", -1)):
            shapes = p.getCollisionShapeData(w.robot, links[name])
            boxes = [s for s in shapes if s[2] == p.GEOM_BOX]
            assert len(shapes) == 2 and len(boxes) == 1  # the finger mesh and its pad
            assert boxes[0][3] == pytest.approx((0.016, 0.008, 0.016))
            inertial = np.array(p.getDynamicsInfo(w.robot, links[name])[3])
            # shape data are in the link's inertial frame: the pad sits 0.0035 toward the finger's back, 4.3 cm up
            assert np.add(boxes[0][5], inertial) == pytest.approx((0.0, side * 0.0035, 0.043))
    finally:
        w.close()


def test_the_scripted_solution_succeeds_on_the_pads():
    """The pads hold what the hand grasps: PickPlace's scripted solution succeeds on them as on the default."""
    from skillgen_ros.core.sim import SimWorld
    from skillgen_ros.core.tasks import scripted

    w = SimWorld(**contact_settings("robosuite_pads"))
    try:
        w.reset("PickPlace", "D0", 0)
        assert scripted.solve(w).success
    finally:
        w.close()


def test_the_default_is_the_stock_sim_and_unknown_names_are_refused():
    from skillgen_ros.core.generation.sim_env import SimEnvConfig
    from skillgen_ros.core.sim.world import SimConfig

    d = contact_settings(DEFAULT_CONTACT_MODEL)
    assert d == {"finger_pads": SimConfig.finger_pads, "solver_iterations": SimConfig.solver_iterations}
    assert SimEnvConfig().contact_model == DEFAULT_CONTACT_MODEL in CONTACT_MODELS
    for bad in ("robosuite", "", "PYBULLET"):
        with pytest.raises(InvalidInputError, match="unknown contact model") as e:
            contact_settings(bad)
        assert e.value.reason == "INVALID_PARAMETER"
        with pytest.raises(InvalidInputError, match="unknown contact model"):
            SimEnvConfig(contact_model=bad)


def test_the_sim_driver_refuses_an_unknown_contact_model_as_a_parameter_error():
    from skillgen_ros.core.errors import ParameterError
    from skillgen_ros.nodes.sim_driver import SIM_PARAMS, make_world

    params = {k: v[0] for k, v in SIM_PARAMS.items()} | {"control_hz": 20.0, "cameras": []}
    with pytest.raises(ParameterError, match="unknown contact model 'soft'"):
        make_world(lambda k: {**params, "contact_model": "soft"}[k])
    w = make_world(lambda k: {**params, "contact_model": "robosuite_pads"}[k])
    assert w.cfg.finger_pads and w.cfg.solver_iterations == 200
    w.close()


def test_demos_make_refuses_an_unknown_contact_model_before_the_sim_starts(tmp_path):
    from skillgen_ros.cli.demos import make

    with pytest.raises(InvalidInputError, match="unknown contact model"):
        make(["Square"], 1, 1, tmp_path, False, contact_model="soft")
    assert not any(tmp_path.iterdir())

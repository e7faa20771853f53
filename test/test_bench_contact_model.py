"""bench/datagen/contact_model.py: each arm changes its part of the sim, and the in-hand turn is measured.
(The pads themselves: test_sim_contact_model.py.)"""
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation as R


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
    from skillgen_ros.core.sim import world

    stock_spawn, stock_init = world.SimWorld._spawn, world.SimWorld.__init__
    try:
        contact_model.use_model("hz:480+iterations:100")
        w = world.SimWorld()
        assert (w.cfg.physics_hz, w.cfg.solver_iterations, w.substeps) == (480.0, 100, 24)
        w.close()
        contact_model.use_model("mass:needle:10")
        assert world.SimWorld._spawn is not stock_spawn
        contact_model.use_model("pads")
        assert world.SimWorld._spawn is stock_spawn
        w = world.SimWorld()
        assert w.cfg.finger_pads and w.cfg.solver_iterations == 50 and w._urdf.endswith("_pads.urdf")
        w.close()
        for bad in ("softer", "ring:soft", "mass:needle", "mass:needle:-1", "ring:0", "pads:2", "mass::3", "pads+", "hz:250", "iterations:x"):
            with pytest.raises(SystemExit, match="unknown arm"):
                contact_model.use_model(bad)
    finally:
        contact_model.use_model("stock")
    assert world.SimWorld._spawn is stock_spawn and world.SimWorld.__init__ is stock_init


def test_an_arm_for_an_object_the_task_lacks_is_refused_before_any_attempt():
    from bench.datagen import contact_model

    assert contact_model.parse_arm("mass:needle:10") == [("mass", "needle", 10.0)]
    assert contact_model.parse_arm("pads+ring:300") == [("pads", "", 0.0), ("ring", "tripod", 300.0)]
    with pytest.raises(SystemExit, match="Square has no object 'tripod'"):
        contact_model.run_arm("ring:300", "Square", "D0", [1000], 1, 0.05)


def test_datagen_keeps_each_contact_models_cells_in_their_own_json(tmp_path, monkeypatch):
    """bench/datagen/run.py --contact-model: never into the default table, never mixed with another model's
    cells, and never on demos made on another model; all refused before any demo is made or cell runs."""
    import json

    from bench.datagen import run

    pads = ["--contact-model", "robosuite_pads", "--tasks", "Square", "--variants", "D0", "--attempts", "1"]
    with pytest.raises(SystemExit, match="their own JSON"):
        run.main(pads + ["--skip-extras"])  # the default --out: the shipped table's
    with pytest.raises(SystemExit, match="their own JSON"):
        run.main(pads + ["--out", str(tmp_path / "pads.json")])  # the extras run on the default model only
    held = tmp_path / "stock.json"
    held.write_text(json.dumps({"cells": [{"task": "Square", "variant": "D0", "method": "skillgen",
                                           "augment": False, "profile": "paper"}]}))
    with pytest.raises(SystemExit, match="holds the pybullet model's"):
        run.main(pads + ["--skip-extras", "--out", str(held)])
    assert not (tmp_path / "pads.json").exists()

    monkeypatch.setattr(run, "ROOT", tmp_path)
    listing = tmp_path / "out" / "demos" / "robosuite_pads" / "Square" / "subsets.yaml"
    listing.parent.mkdir(parents=True)
    listing.write_text("task: Square\ncontact_model: pybullet\n")
    with pytest.raises(SystemExit, match="made on 'pybullet', not 'robosuite_pads'"):
        run.source_demo_dir("Square", "robosuite_pads")
    assert run.source_demo_dir("Square") == tmp_path / "bags" / "Square"

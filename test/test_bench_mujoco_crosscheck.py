"""bench/datagen/mujoco_crosscheck.py, the parts that need no MuJoCo: the nut it gives robosuite and the
fingertip depth it aligns robosuite's gripper to (robosuite itself is not a project dependency)."""
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from bench.datagen.mujoco_crosscheck import our_nut_xml, pybullet_tip_depth
from skillgen_ros.core.tasks import get_task


def test_our_nut_xml_is_our_nut_about_robosuites_body_origin(tmp_path):
    root = ET.parse(our_nut_xml(tmp_path / "nut.xml")).getroot()
    geoms = root.findall(".//geom")
    assert len(geoms) == 5 and {g.get("type") for g in geoms} == {"box"}
    vec = lambda g, k: np.array([float(v) for v in g.get(k).split()])  # noqa: E731
    mass = sum(float(g.get("density")) * 8 * np.prod(vec(g, "size")) for g in geoms)
    nut = {o.id: o for o in get_task("Square").objects_for("D0")}["square_nut"]
    assert mass == pytest.approx(nut.mass, rel=1e-4)  # 50 g, not robosuite's 15.8 g
    # robosuite's on_peg reads the body origin: it must be the ring's centre, walls symmetric about it
    walls = sorted(round(float(vec(g, "pos")[0]), 4) for g in geoms if abs(vec(g, "pos")[1]) < 1e-9)
    assert walls[:2] == [-0.029, 0.029] and walls[2] == pytest.approx(0.0625)  # the handle beyond the +x wall
    assert {g.get("friction") for g in geoms} == {"0.95 0.3 0.1"}  # robosuite's contact parameters
    assert {s.get("name") for s in root.iter("site")} >= {"handle_site", "center_site"}


def test_pybullet_fingertips_reach_past_grasptarget_as_the_urdf_says():
    from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv

    env = SimGenerationEnv(SimEnvConfig(perception="ground_truth", seed=0))
    try:
        env.reset("Square", "D0", 0)
        # panda.urdf: finger joints 0.0584 past panda_hand, finger.obj 0.053849 long, grasptarget 0.105 past the hand
        assert pybullet_tip_depth(env) == pytest.approx(0.0584 + 0.053849 - 0.105, abs=2e-4)
    finally:
        env.close()

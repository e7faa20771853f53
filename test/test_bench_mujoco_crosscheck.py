"""bench/datagen/mujoco_crosscheck.py and robosuite_env.py, the parts that need no MuJoCo: the nuts they give
robosuite, the names they map our objects to, and the fingertip depth they align robosuite's gripper to
(robosuite itself is not a project dependency)."""
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from bench.datagen.mujoco_crosscheck import pybullet_tip_depth
from bench.datagen.robosuite_env import ROBOSUITE_TASKS, our_nut_xml
from skillgen_ros.core.tasks import get_task

vec = lambda g, k: np.array([float(v) for v in g.get(k).split()])  # noqa: E731


def test_our_nut_xml_is_our_nut_about_robosuites_body_origin(tmp_path):
    nut = get_task("Square").object("square_nut")
    root = ET.parse(our_nut_xml(nut, tmp_path / "nut.xml")).getroot()
    geoms = root.findall(".//geom")
    assert len(geoms) == 5 and {g.get("type") for g in geoms} == {"box"}
    mass = sum(float(g.get("density")) * 8 * np.prod(vec(g, "size")) for g in geoms)
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


def test_our_round_nut_xml_matches_robosuites_octagon_about_the_ring_centre(tmp_path):
    """round-nut.xml: eight 2.25 x 4.5 cm walls centred 4.245 cm from the body origin, handle box at x 0.06."""
    nut = get_task("NutAssembly").object("round_nut")
    geoms = ET.parse(our_nut_xml(nut, tmp_path / "round.xml")).getroot().findall(".//geom")
    assert len(geoms) == 9
    radii = sorted(round(float(np.linalg.norm(vec(g, "pos")[:2])), 4) for g in geoms)
    assert radii[:8] == [0.0425] * 8 and radii[8] == pytest.approx(0.06, abs=1e-4)
    mass = sum(float(g.get("density")) * 8 * np.prod(vec(g, "size")) for g in geoms)
    assert mass == pytest.approx(nut.mass, rel=1e-4)


def test_robosuite_names_cover_each_tasks_nuts_and_pegs():
    for task, spec in ROBOSUITE_TASKS.items():
        ids = {o.id for o in get_task(task).objects_for("D0")}
        assert set(spec.nuts) | set(spec.pegs) == ids  # every object mapped, none invented
        assert set(spec.nut_peg) == set(spec.nuts) and set(spec.nut_peg.values()) == set(spec.pegs)

"""ament_python package for skillgen_ros.

colcon honours setup.cfg and puts the console scripts in lib/skillgen_ros; a pip install puts
them in bin/, and scripts/bootstrap.sh links them into <venv>/lib/skillgen_ros so that the
ament-index lookup `ros2 run` does (prefix/lib/<pkg>/<exe>) works on pip-only machines too.
"""
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = "skillgen_ros"
HERE = Path(__file__).resolve().parent


def _extra_pins() -> dict:
    """name -> "name==version" from requirements-extras.txt, the one place the extras are pinned."""
    lines = (HERE / "requirements-extras.txt").read_text().splitlines()
    return {ln.split("==")[0].strip(): ln.strip() for ln in lines if "==" in ln and not ln.lstrip().startswith("#")}


# Optional extras (issue 24): `pip install .[lerobot]` (skillgen dataset export --format lerobot),
# `.[robomimic]` (robomimic's own loaders). In this project's venv, scripts/bootstrap.sh installs
# them from requirements-extras.txt with --no-deps instead: lerobot 0.4.4 declares torch<2.11 and
# robomimic 0.3.0 an unpinned torchvision, and resolving either would replace the pinned torch 2.13.
_PINS = _extra_pins()
EXTRAS = {"lerobot": [_PINS["lerobot"]], "robomimic": [_PINS["robomimic"]]}

# One place lists the executables: name -> module:function. Nodes start through nodes/entry.py,
# which makes Ctrl-C quiet before the node's slow imports.
EXECUTABLES = {
    "sim_driver": "skillgen_ros.nodes.entry:sim_driver",
    "mock_driver": "skillgen_ros.nodes.entry:mock_driver",
    "perception": "skillgen_ros.nodes.entry:perception",
    "planner": "skillgen_ros.nodes.entry:planner",
    "skill_replay": "skillgen_ros.nodes.entry:skill_replay",
    "datagen": "skillgen_ros.nodes.entry:datagen",
    "hsp": "skillgen_ros.nodes.entry:hsp",
    "recorder": "skillgen_ros.nodes.entry:recorder",
    "player": "skillgen_ros.nodes.entry:player",
    "teleop": "skillgen_ros.nodes.entry:teleop",
    "container": "skillgen_ros.nodes.entry:container",
    "skillgen": "skillgen_ros.cli.main:main",
}

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*", "bench", "bench.*"]),
    package_data={PACKAGE: ["graphs.yaml", "core/tasks/meshes/*", "core/tasks/*.yaml", "core/planning/*.yaml"]},
    include_package_data=True,
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/params", glob("params/*.yaml")),
        (f"share/{PACKAGE}/launch", glob("launch/*.py")),
    ],
    install_requires=["setuptools"],
    extras_require=EXTRAS,
    zip_safe=False,
    maintainer="skillgen_ros developers",
    maintainer_email="skillgen@example.com",
    description="SkillMimicGen demonstration generation for ROS 2 Jazzy",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [f"{k} = {v}" for k, v in EXECUTABLES.items()],
        # The pytest plugin (docs/testing.md). The entry point's name is the module's name, so a
        # conftest's `pytest_plugins = ["skillgen_ros.testing"]` finds it registered and skips it.
        "pytest11": ["skillgen_ros.testing = skillgen_ros.testing"],
    },
)

"""ament_python package for skillgen_ros.

colcon honours setup.cfg and puts the console scripts in lib/skillgen_ros; a pip install puts
them in bin/, and scripts/bootstrap.sh links them into <venv>/lib/skillgen_ros so that the
ament-index lookup `ros2 run` does (prefix/lib/<pkg>/<exe>) works on pip-only machines too.
"""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = "skillgen_ros"

# One place lists the executables: node name -> module:function.
EXECUTABLES = {
    "sim_driver": "skillgen_ros.nodes.sim_driver:main",
    "mock_driver": "skillgen_ros.nodes.mock_driver:main",
    "perception": "skillgen_ros.nodes.perception:main",
    "planner": "skillgen_ros.nodes.planner:main",
    "skill_replay": "skillgen_ros.nodes.skill_replay:main",
    "datagen": "skillgen_ros.nodes.datagen:main",
    "hsp": "skillgen_ros.nodes.hsp:main",
    "recorder": "skillgen_ros.nodes.recorder:main",
    "player": "skillgen_ros.nodes.player:main",
    "teleop": "skillgen_ros.nodes.teleop:main",
    "container": "skillgen_ros.nodes.container:main",
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
    zip_safe=False,
    maintainer="skillgen_ros developers",
    maintainer_email="skillgen@example.com",
    description="SkillMimicGen demonstration generation for ROS 2 Jazzy",
    license="Apache-2.0",
    entry_points={"console_scripts": [f"{k} = {v}" for k, v in EXECUTABLES.items()]},
)

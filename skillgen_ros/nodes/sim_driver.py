"""sim_driver node: the pybullet Panda (core.sim.SimWorld) behind the driver interface.

Interface, timing modes and input policy: nodes/driver_base.py. Extra parameters here: physics
rate, OSC gains (robosuite OSC_POSE defaults, critically damped at damping_ratio 1), joint
computed-torque gain, the gripper force and the contact model.
"""
from __future__ import annotations

import sys

from skillgen_ros.core.sim.contact_model import DEFAULT_CONTACT_MODEL
from skillgen_ros.nodes.runtime import run_node

SIM_PARAMS = {
    "physics_hz": (240.0, "physics rate; an integer multiple of control_hz"),
    "osc_kp_pos": (150.0, "OSC position stiffness (kd = 2 * damping_ratio * sqrt(kp))"),
    "osc_kp_ori": (150.0, "OSC orientation stiffness"),
    "osc_damping_ratio": (1.0, "OSC damping ratio (1 = critically damped)"),
    "osc_kp_null": (10.0, "nullspace posture stiffness toward Q_HOME"),
    "joint_kp": (400.0, "joint-trajectory computed-torque stiffness (critically damped)"),
    "gripper_force": (20.0, "finger force limit for OSC gripper commands (N per finger)"),
    "gripper_hold_force": (2.0, "finger force once an opening move reached its width (N per finger)"),
    "contact_model": (DEFAULT_CONTACT_MODEL, "how the hand holds objects: pybullet | robosuite_pads "
                                             "(core/sim/contact_model.py)"),
}


def make_world(param):
    from skillgen_ros.core.errors import ParameterError, SkillGenError
    from skillgen_ros.core.sim.contact_model import contact_settings
    from skillgen_ros.core.sim.control import JointGains, OscGains
    from skillgen_ros.core.sim.world import SimConfig, SimWorld
    from skillgen_ros.nodes.driver_cameras import camera_configs

    try:
        cfg = SimConfig(control_hz=float(param("control_hz")), physics_hz=float(param("physics_hz")),
                        osc=OscGains(float(param("osc_kp_pos")), float(param("osc_kp_ori")),
                                     float(param("osc_damping_ratio")), float(param("osc_kp_null"))),
                        joint=JointGains(float(param("joint_kp"))), gripper_force=float(param("gripper_force")),
                        gripper_hold_force=float(param("gripper_hold_force")), cameras=camera_configs(param),
                        **contact_settings(str(param("contact_model"))))
        return SimWorld(cfg)
    except SkillGenError as e:
        raise ParameterError(str(e))


def sim_driver():
    from skillgen_ros.nodes.driver_base import DriverNode

    return DriverNode("sim_driver", make_world, SIM_PARAMS)


def main(args=None) -> int:
    return run_node(sim_driver, args)


if __name__ == "__main__":
    sys.exit(main())

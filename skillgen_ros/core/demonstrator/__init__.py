"""Scripted human-like demonstrator: exists ONLY to produce the shipped source demos (bags/).

SkillMimicGen starts from a few human demonstrations. To ship reproducible ones without a
person at the keyboard, `ScriptedDemonstrator` drives the simulator's OSC interface the way a
person would (smooth, not optimal, different every demo). It uses privileged sim state, is never
part of data generation, and `skillgen demos record` (teleop) is the way to record real human demos.
"""
from .human_like import ScriptedDemonstrator  # noqa: F401
from .motion import DemoStyle  # noqa: F401
from .record import DemoRollout, DemoStep  # noqa: F401

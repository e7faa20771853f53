"""The Franka hand's finger motors: a grasp keeps its force on, an opening move drops to a hold force.

On the real hand `grasp()` squeezes until told otherwise while `move()` stops pushing once it
arrives. Modelling that matters here: a 20 N open finger that a nut pushes on drags the nut up
its peg on the retreat, a 2 N one yields. `FrankaHand` is that mode (command, target, force,
opening) and the motor call that applies it; SimWorld owns one and asks it every physics step.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InvalidInputError
from ..robot import GRIPPER_MAX_WIDTH
from .commands import validate_gripper

GRASP_MIN_WIDTH = 0.002  # fingers closed on nothing stop below this width
OPEN_REACHED = 0.001     # an opening move within this of its width has arrived
STATE_SIZE = 5           # command, finger target, finger force, commanded force, opening


@dataclass
class FrankaHand:
    grasp_force: float      # N per finger while closing / holding a grasp (SimConfig.gripper_force)
    hold_force: float       # N per finger once an opening move has arrived
    command: float = -1.0   # last command, -1 open .. +1 closed (robosuite convention)
    target: float = GRIPPER_MAX_WIDTH / 2  # per-finger position target (m)
    force: float = field(init=False)            # force the motors apply now
    commanded_force: float = field(init=False)  # force of the last command (a repeat is no new move)
    opening: bool = False

    def __post_init__(self):
        if not (0.0 <= self.hold_force <= self.grasp_force < np.inf):
            raise InvalidInputError("need 0 <= gripper_hold_force <= gripper_force, both finite")
        self.force, self.commanded_force = self.hold_force, self.grasp_force  # open and arrived

    # -- commands (they return whether the motors need the new mode)
    def close_open(self, command: float, width_now: float) -> bool:
        """-1 open .. +1 closed, force-limited by grasp_force."""
        g = validate_gripper(command)
        self.command = g
        return self._move((1.0 - g) / 2.0 * GRIPPER_MAX_WIDTH / 2.0, self.grasp_force, width_now)

    def move_to(self, width: float, max_effort: float, width_now: float) -> bool:
        """Opening `width` (m) with at most `max_effort` N per finger."""
        if not (np.isfinite(width) and np.isfinite(max_effort)) or max_effort <= 0:
            raise InvalidInputError(f"gripper width {width} / effort {max_effort} invalid")
        half = float(np.clip(width, 0.0, GRIPPER_MAX_WIDTH)) / 2.0
        self.command = 1.0 - 2.0 * half * 2.0 / GRIPPER_MAX_WIDTH
        return self._move(half, float(max_effort), width_now)

    def _move(self, half_width: float, force: float, width_now: float) -> bool:
        """Closing is a grasp: the force stays on. Opening is a move that drops to hold_force once
        it arrives. A repeated command does not restart the move."""
        if half_width == self.target and force == self.commanded_force:
            return False
        self.opening = half_width * 2.0 > width_now + OPEN_REACHED
        self.target, self.force, self.commanded_force = half_width, force, force
        return True

    def arrived(self, width_now: float) -> bool:
        """Each physics step: an opening move that reached its width drops to the hold force (True
        when the motors need the new force)."""
        if self.opening and width_now >= 2.0 * self.target - OPEN_REACHED:
            self.opening, self.force = False, min(self.force, self.hold_force)
            return True
        return False

    def is_grasping(self, width_now: float) -> bool:
        """Fingers commanded closed but stalled on something before fully closing."""
        return bool(self.target < GRIPPER_MAX_WIDTH / 4 and width_now > GRASP_MIN_WIDTH)

    def apply(self, client, robot: int, fingers: list[int]) -> None:
        client.setJointMotorControlArray(robot, fingers, client.POSITION_CONTROL, targetPositions=[self.target] * 2,
                                         forces=[self.force] * 2, positionGains=[0.05] * 2)

    # -- save / restore (SimWorld.get_state's tail)
    def state(self) -> list[float]:
        return [self.command, self.target, self.force, self.commanded_force, float(self.opening)]

    def set_state(self, s) -> None:
        c, t, f, cf, o = (float(x) for x in s)
        if not (-1.0 <= c <= 1.0 and 0.0 <= t <= GRIPPER_MAX_WIDTH / 2 and 0.0 <= f and 0.0 <= cf):
            raise InvalidInputError(f"gripper mode {[c, t, f, cf, o]} is out of range")
        self.command, self.target, self.force, self.commanded_force, self.opening = c, t, f, cf, bool(o)

"""Coffee Prep's privileged scripted solution (core/tasks/scripted_coffee_prep.py, through `scripted.solve`) solves
D0 in the pybullet sim through the OSC interface only: the lid stays shut until the mug is on the drip base and
is then swung open past upright, the drawer slides past MimicGen's drawer_open after that, and at the end the
mug stands on the base, the pod is in the holder and the lid is closed. Budgets are control periods, never wall
time (D0 10/10 seeds measured; one seed here)."""
from __future__ import annotations

import numpy as np
import pytest

from skillgen_ros.core.sim import SimWorld
from skillgen_ros.core.tasks import coffee as C
from skillgen_ros.core.tasks import coffee_prep as CP
from skillgen_ros.core.tasks import get_task, scripted
from skillgen_ros.core.tasks.articulation import joint_key

TASK = get_task("CoffeePreparation")
M, POD, MUG = (TASK.object(k) for k in ("coffee_machine", "coffee_pod", "mug"))
LID, SLIDE = joint_key("coffee_machine", "lid"), joint_key("drawer", "slide")
BUDGET = 1200   # control periods (60 s at 20 Hz); the script takes about 1000


@pytest.fixture(scope="module")
def world():
    w = SimWorld()
    yield w
    w.close()


class _Watched:
    """The world as scripted.solve sees it (an env: scripted.py's docstring), recording the joints each period."""

    def __init__(self, world):
        self.world, self.lid, self.slide = world, [], []

    def __getattr__(self, name):
        return getattr(self.world, name)

    def step(self, pose, gripper):
        self.world.step(pose, gripper)
        joints = self.world.object_joints()
        self.lid.append(joints[LID])
        self.slide.append(joints[SLIDE])


def test_solve_does_the_five_skills_on_d0(world):
    world.reset("CoffeePreparation", "D0", 0)
    assert not world.task_success()
    env = _Watched(world)
    result = scripted.solve(env)
    assert result.success and result.steps == len(result.actions) < BUDGET
    lid, slide = np.array(env.lid), np.array(env.slide)
    opened = int(np.argmax(lid > np.pi / 2))          # the lid swung past upright (it then rests open) ...
    assert lid.max() < C.LID_UPPER + 0.01 and opened > 0
    assert np.abs(lid[:opened]).max() < np.pi / 2     # ... once, with the lid shut before: the mug went in under it
    assert slide.min() < CP.DRAWER_OPEN and int(np.argmax(slide < CP.DRAWER_OPEN)) > opened   # then the drawer
    state = world.scene_state()
    assert C.pod_in_holder(M, POD, state) and C.lid_closed(M, state) and CP.mug_placed(M, MUG, state)


def test_the_mug_yaw_bound_is_the_pitched_hands_range_at_grasp_and_placement():
    from skillgen_ros.core.tasks import scripted_coffee_prep as S

    assert S.mug_yaws_allowed(0.0, 0.0, 1)           # straight ahead: EE yaw 0 at both
    assert not S.mug_yaws_allowed(0.0, 0.0, -1)      # the turned hand: EE yaw 180 deg
    a, turn = S.MUG_GRASP_MAX_YAW, S.MUG_GRASP_MAX_YAW - S.MUG_MAX_YAW   # grasp at its bound, turned back to 80 deg
    assert S.mug_yaws_allowed(a, a - turn, 1)
    assert not S.mug_yaws_allowed(a, a - turn + np.radians(1.0), 1)     # placement 1 deg past its bound
    assert not S.mug_yaws_allowed(a + np.radians(1.0), a - turn, 1)     # grasp 1 deg past its bound

"""Every task/variant: success is false at reset and true after the privileged scripted solution,
driven only through the OSC interface (SimWorld.step with absolute EE targets + gripper).
One seed per variant keeps the suite fast; bench/sim_driver reports rates over more seeds."""
from __future__ import annotations

import pytest

from skillgen_ros.core.sim import SimWorld
from skillgen_ros.core.tasks import TASK_NAMES, get_task, scripted

CASES = [(t, v) for t in TASK_NAMES for v in get_task(t).variants]
# NutAssembly D2 seed 0 puts the round nut's handle 0.87 m out at table height, past the Panda's top-down
# reach (the paper's 0.5 m region reaches 0.81 m; bench/reachability measures the fraction), so it takes seed 1.
SEEDS = {("NutAssembly", "D2"): 1}


@pytest.fixture(scope="module")
def world():
    w = SimWorld()
    yield w
    w.close()


@pytest.mark.parametrize("task,variant", CASES)
def test_scripted_solution_through_osc(world, task, variant):
    world.reset(task, variant, SEEDS.get((task, variant), 0))
    assert not world.task_success()
    result = scripted.solve(world)
    assert result.success, world.object_poses()
    assert result.steps == len(result.actions) and result.steps < 600

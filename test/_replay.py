"""Open-loop replay of shipped demos, for the tests that guard the bags against sim changes.

An open-loop replay of a contact-rich demo is not bit-exact across CPUs (numba and BLAS pick kernels per
CPU): Threading demo_00 fails on an AMD EPYC (znver5), Coffee Prep demo_00 on an Intel Xeon (rocketlake),
where the other 9 of 10 still replay (bench/source_demos). So the tests ask two of the first three.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from skillgen_ros.core.geometry import Pose
from skillgen_ros.core.skills import bag_demos as B

FIRST, NEEDED = 3, 2


def replay_open_loop(paths: Sequence[Path], check: Callable | None = None) -> dict[str, bool]:
    """{bag: success} for each bag replayed from its recorded scene; success is the task's check and, when
    given, check(world) (a lid shut, a drawer closed). The scene starts unsolved."""
    from skillgen_ros.core.sim import SimWorld

    world = SimWorld()
    replayed = {}
    try:
        for path in paths:
            reader = B.open_bag(path)
            scene, arrays = B.read_scene(reader), B.read_demo_arrays(path, reader)
            world.reset(scene.task, scene.variant, scene.seed)
            assert not world.task_success(), path
            for p, q, g in zip(arrays.action_positions, arrays.action_quaternions, arrays.gripper):
                world.step(Pose(p, q), float(g))
            replayed[str(path)] = bool(world.task_success() and (check is None or check(world)))
    finally:
        world.close()
    return replayed


def assert_most_replay(paths: Sequence[Path], task: str, check: Callable | None = None) -> None:
    replayed = replay_open_loop(list(paths)[:FIRST], check)
    assert sum(replayed.values()) >= NEEDED, (f"shipped demos no longer replay to success ({replayed}): remake them "
                                              f"with `skillgen demos make --task {task} --force`")

"""ThreePieceAssembly end to end in-process: the shipped source demos, Algorithm 1 (paper profile) on the
pybullet sim, a dataset of successful 4-skill demos. Seeded: attempt (seed 1000, index 0) succeeds."""
import h5py

from conftest import REPO
from skillgen_ros.core.generation.session import RunRequest, run_generation
from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv
from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos
from skillgen_ros.core.tasks import get_task


def test_skillgen_generates_a_successful_three_piece_assembly_demo(tmp_path):
    task = get_task("ThreePieceAssembly")
    demos = load_source_demos(expand_bag_paths([str(REPO / "bags" / "ThreePieceAssembly")]), task)
    assert len(demos) == 10 and all(len(d.skills) == 4 for d in demos)
    env = SimGenerationEnv(SimEnvConfig(perception="ground_truth", seed=1000))
    try:
        req = RunRequest(task="ThreePieceAssembly", variant="D0", method="skillgen", attempts=1, seed=1000,
                         output_dir=str(tmp_path / "run"), video_attempts=0, profile="paper")
        run = run_generation(env, demos, task, req, write_report=False, keep_timings=False)
    finally:
        env.close()
    assert run.successes == 1, dict(run.failures)
    with h5py.File(run.dataset_path, "r") as f:
        names = list(f["data"])
        assert len(names) == 1
        demo = f["data"][names[0]]
        assert demo["actions"].shape[0] > 100

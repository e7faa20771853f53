"""The bootstrap's warm step (skillgen_ros/core/planning/warm.py) leaves numba's cache holding every
kernel signature the planner node compiles at start-up: a second process loads them all, compiling
nothing. A planner node that compiles cannot act on Ctrl-C (CI, 2026-12-06)."""
import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

PROBE = """
import json
from numba.core.registry import CPUDispatcher
from skillgen_ros.core.planning import kernels, warm
warm.warm_kernels()
stats = {n: (sum(f.stats.cache_hits.values()), sum(f.stats.cache_misses.values()))
         for n, f in vars(kernels).items() if isinstance(f, CPUDispatcher)}
print(json.dumps(stats))
"""


def _run(cache_dir):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir), PYTHONPATH=str(REPO))
    r = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=600, env=env, cwd=REPO)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_a_warmed_cache_serves_every_start_up_kernel_without_compiling(tmp_path):
    cold = _run(tmp_path)
    assert sum(hits for hits, _ in cold.values()) == 0  # an empty cache: everything compiled
    warm = _run(tmp_path)
    assert all(misses == 0 for _, misses in warm.values()), warm
    loaded = {n for n, (hits, _) in warm.items() if hits}
    # the entry points the planner node's start-up calls (inlined helpers are never dispatched)
    assert {"ik_iterate", "collide_spheres", "sphere_centres", "seed_rng", "link_poses_batch"} <= loaded, warm

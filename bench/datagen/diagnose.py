"""bench/datagen/diagnose.py: why a cell falls short of the paper -- success per source demo, with and
without action noise, and the task-state at each failure.

A skillgen attempt replays one source demo's skills; on a tight insertion (Threading: a 1 cm shaft
through a 1.6 cm ring, 3 mm a side; Square: 7 mm a side) how that demo's own insertion went decides
most of the outcome. This splits a cell's rate by the demo used, once with the run's action noise
(0.05, the paper's) and once with none, so demo quality, noise and planning can be told apart.

    .venv/bin/python bench/datagen/diagnose.py --task Threading --variant D0 --attempts 60 \
        [--noise 0.05 0.0] [--seed 2000] [--profile paper]
    .venv/bin/python bench/datagen/diagnose.py --task Square --variant D1_clutter --method mimicgen \
        --noise 0.05 --seed 1000 --attempts 100 --touch obstacle
    .venv/bin/python bench/datagen/diagnose.py --task CoffeePreparation --variant D0 --method mimicgen \
        --noise 0.05 --seed 1000 --attempts 40 --stages   # the furthest stage each failed attempt reached

Writes (merging into) bench/results/datagen_diagnosis.json, one entry per (task, variant, noise, seed).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.machine import machine_info  # noqa: E402

OUT = ROOT / "bench" / "results" / "datagen_diagnosis.json"


def _count_touches(env, body: str) -> list[int]:
    """Wrap env.step to count the control steps in which the robot touches `body` (pybullet
    contact points): counter[0] is reset by the caller before each attempt."""
    counter = [0]
    step = env.step

    def counted(target, gripper):
        obs = step(target, gripper)
        if body in env.world.bodies and env.world.robot_in_collision_with([body]):
            counter[0] += 1
        return obs
    env.step = counted
    return counter


LIFTED, LID_OPENED = 0.05, 1.3   # m above its start; rad (the demos swing the lid to 1.55-1.8 rad)


def _coffee_prep_stage(obs: dict) -> str:
    """How far a failed Coffee Prep attempt got, from its recorded true object poses and joint values."""
    from skillgen_ros.core.tasks import coffee as C
    from skillgen_ros.core.tasks import coffee_prep as CP

    mug, pod = np.asarray(obs["mug_pose"])[:, 2], np.asarray(obs["coffee_pod_pose"])[:, 2]
    lid, slide = np.asarray(obs["coffee_machine_joints"])[:, 0], np.asarray(obs["drawer_joints"])[:, 0]
    if mug.max() - mug[0] < LIFTED:
        return "1 mug not lifted"
    if lid.max() < LID_OPENED:
        return "2 lid never opened"
    if slide.min() > CP.DRAWER_OPEN:
        return "3 drawer not opened"
    if pod.max() - pod[0] < LIFTED:
        return "4 pod not lifted"
    if lid[-1] > C.LID_CLOSED_TOLERANCE:
        return "5 pod carried, lid not closed"
    return "6 lid closed, pod or mug not in place"


STAGES = {"CoffeePreparation": _coffee_prep_stage}   # tasks whose failures --stages can place


def diagnose(task: str, variant: str, attempts: int, noise: float, seed: int, profile: str,
             method: str = "skillgen", touch: str = "", stages: bool = False) -> dict:
    """One cell's attempts, grouped by the source demo of the last skill (the insertion's); with
    `touch`, also how many attempts pushed the robot against that body, and how many of those
    still succeeded (pybullet lets the arm shove past a fixed obstacle and keep its grasp)."""
    from skillgen_ros.core.generation.attempt import run_attempt
    from skillgen_ros.core.generation.session import RunRequest
    from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv
    from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos
    from skillgen_ros.core.tasks import get_task

    spec = get_task(task)
    demos = load_source_demos(expand_bag_paths([str(ROOT / "bags" / task)]), spec)
    cfg = RunRequest(task=task, variant=variant, method=method, attempts=attempts, seed=seed, profile=profile,
                     action_noise=noise, output_dir="/nonexistent").config()
    env = SimGenerationEnv(SimEnvConfig(perception="ground_truth", seed=seed, video=False))
    by_demo: dict[int, list[int]] = defaultdict(lambda: [0, 0])
    reasons: Counter = Counter()
    reached: Counter = Counter()
    touching = _count_touches(env, touch) if touch else None
    touched = [0, 0]  # attempts touching `touch`, and how many of them succeeded
    t0 = time.perf_counter()
    try:
        for i in range(attempts):
            if touching:
                touching[0] = 0
            r = run_attempt(env, demos, spec, method, i, seed, cfg)
            if touching and touching[0] > 0:
                touched[0] += 1
                touched[1] += int(r.success)
            d = int(r.source_demos[-1]) if r.source_demos else -1
            by_demo[d][0] += int(r.success)
            by_demo[d][1] += 1
            if not r.success:
                reasons[f"{r.reason.value}: {r.message[:80]}"] += 1
                if stages and r.reason.value == "TASK_FAILED":
                    reached[STAGES[task](r.episode.obs)] += 1
    finally:
        env.close()
    n_ok = sum(v[0] for v in by_demo.values())
    extra = {"touch": touch, "attempts_touching": touched[0], "successes_touching": touched[1]} if touch else {}
    if stages:
        extra["task_failed_stages"] = dict(sorted(reached.items()))
    return {"task": task, "variant": variant, "method": method, "profile": profile, "seed": seed, "action_noise": noise,
            "attempts": attempts, "successes": n_ok, "rate": n_ok / attempts,
            "by_source_demo": {str(k): {"successes": v[0], "attempts": v[1]} for k, v in sorted(by_demo.items())},
            "failures": dict(reasons.most_common()), "wall_seconds": time.perf_counter() - t0, **extra}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", required=True)
    ap.add_argument("--variant", default="D0")
    ap.add_argument("--attempts", type=int, default=60)
    ap.add_argument("--noise", type=float, nargs="+", default=[0.05, 0.0])
    ap.add_argument("--seed", type=int, default=2000)
    ap.add_argument("--profile", default="paper")
    ap.add_argument("--method", default="skillgen", choices=["skillgen", "mimicgen"])
    ap.add_argument("--touch", default="", help="also count attempts in which the robot touches this body")
    ap.add_argument("--stages", action="store_true", help=f"the furthest stage each TASK_FAILED attempt reached "
                                                          f"(tasks: {', '.join(STAGES)})")
    a = ap.parse_args(argv)
    if a.stages and a.task not in STAGES:
        ap.error(f"--stages knows the stages of {', '.join(STAGES)} only")
    out = json.loads(OUT.read_text()) if OUT.exists() else {"entries": []}
    out["machine"] = machine_info()
    for noise in a.noise:
        e = diagnose(a.task, a.variant, a.attempts, noise, a.seed, a.profile, a.method, a.touch, a.stages)
        e["command"] = (f".venv/bin/python bench/datagen/diagnose.py --task {a.task} --variant {a.variant} "
                        f"--attempts {a.attempts} --noise {noise} --seed {a.seed} --profile {a.profile} "
                        f"--method {a.method}" + (f" --touch {a.touch}" if a.touch else "")
                        + (" --stages" if a.stages else ""))

        def key(x):
            return (x["task"], x["variant"], x.get("method", "skillgen"), x["action_noise"], x["seed"], x["profile"])
        out["entries"] = [x for x in out["entries"] if key(x) != key(e)] + [e]
        OUT.write_text(json.dumps(out, indent=1) + "\n")
        per = ", ".join(f"{k}: {v['successes']}/{v['attempts']}" for k, v in e["by_source_demo"].items())
        touch = f" | touching {a.touch}: {e['attempts_touching']} ({e['successes_touching']} succeeded)" if a.touch else ""
        touch += f" | stages {e['task_failed_stages']}" if a.stages else ""
        print(f"{a.task} {a.variant} {a.method} noise {noise}: {e['successes']}/{e['attempts']} | by demo {per}{touch}",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

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
    # A/B of the paper's retreat/approach contact rule on the same seeds (planner.py `movable`)
    .venv/bin/python bench/datagen/diagnose.py --task NutAssembly --variant D1 --noise 0.05 --seed 1000 \
        --attempts 40 [--without-paper-contacts]
    # A/B of the planner's wrist back-out on the same seeds (each entry counts the plans each start repair served)
    .venv/bin/python bench/datagen/diagnose.py --task NutAssembly --variant D1 --profile skillgen_ros \
        --noise 0.05 --seed 1000 --attempts 40 [--without-wrist-backout]
    # MimicGen with its subtask ends moved (an experiment, not the baseline): do the grasped objects drag?
    .venv/bin/python bench/datagen/diagnose.py --task ThreePieceAssembly --variant D0 --method mimicgen \
        --noise 0.05 --seed 1000 --attempts 40 --mimicgen-offsets 25 30

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
from bench.datagen import source_digest  # noqa: E402
from bench.datagen import attempt_tally  # noqa: E402
from bench.datagen.attempt_tally import DRAGGED, SLIPPED, STAGES, Tally  # noqa: E402
from bench.machine import machine_info  # noqa: E402
from skillgen_ros.core.planning.start_repair import START_REPAIRS  # noqa: E402

OUT = ROOT / "bench" / "results" / "datagen_diagnosis.json"


def count_touches(env, body: str) -> list[int]:
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


def _count_start_repairs(env) -> Counter:
    """Wrap env.planner.plan to count, over a run, the plans each start repair served and the plans
    refused START_IN_COLLISION (what a repair's A/B compares on the same seeds)."""
    seen: Counter = Counter()
    plan = env.planner.plan

    def counted(*args, **kwargs):
        r = plan(*args, **kwargs)
        seen["plans"] += 1
        seen.update(k for k, phrase in START_REPAIRS.items() if phrase in r.message)
        if r.status.name == "START_IN_COLLISION":
            seen["START_IN_COLLISION"] += 1
        return r
    env.planner.plan = counted
    return seen


def _record_look_errors(env) -> list[tuple[int, dict]]:
    """Wrap env.estimate_poses (perception "estimate"): per look, the skill it is for and each estimated
    object's translation (mm) and symmetry-aware rotation (deg) error against the sim's true pose, the
    held object left out (its belief is not looked at). The caller clears the list before each attempt;
    each entry is (skill index, {object id: (mm, deg)})."""
    from skillgen_ros.core.perception.metrics import rotation_error

    looks: list[tuple[int, dict]] = []
    estimate = env.estimate_poses

    def recorded():
        est, truth, held = estimate(), env.world.object_poses(), env.grasps.holding()
        looks.append((env.next_skill, {
            k: (1000 * float(np.linalg.norm(v.position - truth[k].position)),
                float(np.degrees(rotation_error(v.rotation.as_matrix(), truth[k].rotation.as_matrix(),
                                                env.model_symmetry(k)))))
            for k, v in est.items() if k in truth and k != held}))
        return est
    env.estimate_poses = recorded
    return looks


def _look_summary(rows: list[tuple[bool, list[tuple[int, dict]]]], skills) -> dict:
    """For each skill, the object it acts on as the first look for that skill saw it: median and max
    error over attempts, split by outcome (an error seen before the skill can cause its failure; one
    seen after a failure, e.g. of a nut knocked over, cannot)."""
    out = {}
    for ok in (True, False):
        errs: dict[str, list[tuple[float, float]]] = defaultdict(list)
        for success, looks in rows:
            if success != ok:
                continue
            for sk in skills:
                first = next((e for i, e in looks if i == sk.index), None)
                if first is not None and sk.object_id in first:
                    errs[f"skill {sk.index} {sk.object_id}"].append(first[sk.object_id])
        out["succeeded" if ok else "failed"] = {
            k: {"attempts": len(v), "trans_mm_median": float(np.median([a for a, _ in v])),
                "trans_mm_max": float(max(a for a, _ in v)), "rot_deg_median": float(np.median([b for _, b in v])),
                "rot_deg_max": float(max(b for _, b in v))} for k, v in sorted(errs.items())}
    return out


def _set_pod_mass(task: str, kg: float) -> None:
    """Build the Coffee pod with another mass (the spec is cached: set before the task is first built)."""
    from skillgen_ros.core.tasks import coffee as C
    from skillgen_ros.core.tasks import get_task

    if task != "Coffee" or not kg > 0:
        raise SystemExit(f"--pod-mass needs --task Coffee and a mass > 0, got {task} {kg}")
    C.POD_MASS = kg
    C.coffee_pod.cache_clear()
    if [o.mass for o in get_task(task).objects if o.id == "coffee_pod"] != [kg]:
        raise SystemExit("the Coffee task was built before --pod-mass could apply")


def diagnose(task: str, variant: str, attempts: int, noise: float, seed: int, profile: str,
             method: str = "skillgen", touch: str = "", stages: bool = False,
             mimicgen_offsets: tuple[int, int] | None = None, augment: bool = False,
             perception: str = "ground_truth", bags: Path | None = None) -> dict:
    """One cell's attempts, grouped by the source demo of the last skill (the insertion's); with
    `touch`, also how many attempts pushed the robot against that body, and how many of those
    still succeeded (pybullet lets the arm shove past a fixed obstacle and keep its grasp). With
    `mimicgen_offsets`, MimicGen's subtask_term_offset_range is replaced for this run (an experiment on
    where its subtasks end, never a baseline number). `bags`: the source demos' folder (default the shipped
    bags/<task>)."""
    from dataclasses import replace

    from skillgen_ros.core.generation import mimicgen as mg
    from skillgen_ros.core.generation.attempt import run_attempt
    from skillgen_ros.core.generation.session import RunRequest
    from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv
    from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos
    from skillgen_ros.core.tasks import get_task

    spec = get_task(task)
    specs_before = dict(mg.MIMICGEN_SPECS)
    if mimicgen_offsets:
        mg.MIMICGEN_SPECS[task] = replace(mg.spec_for(task), offset_range=tuple(mimicgen_offsets))
    bags = Path(bags or ROOT / "bags" / task)
    source = source_digest.record(bags)  # which demos: an entry from remade demos is another entry
    demos = load_source_demos(expand_bag_paths([str(bags)]), spec)
    cfg = RunRequest(task=task, variant=variant, method=method, attempts=attempts, seed=seed, profile=profile,
                     action_noise=noise, augment=augment, output_dir="/nonexistent").config()
    env = SimGenerationEnv(SimEnvConfig(perception=perception, seed=seed, video=False))
    tally = Tally(task, stages)
    touching = count_touches(env, touch) if touch else None
    repairs = _count_start_repairs(env)
    looks = _record_look_errors(env) if perception == "estimate" else None
    t0 = time.perf_counter()
    try:
        for i in range(attempts):
            if touching:
                touching[0] = 0
            if looks is not None:
                looks.clear()
            tally.add(run_attempt(env, demos, spec, method, i, seed, cfg), spec, looks, touching)
    finally:
        env.close()
        mg.MIMICGEN_SPECS.clear()
        mg.MIMICGEN_SPECS.update(specs_before)
    extra = {"touch": touch, "attempts_touching": tally.touched[0], "successes_touching": tally.touched[1]} if touch else {}
    if mimicgen_offsets:
        extra["mimicgen_offsets"] = list(mimicgen_offsets)
    extra["plans"] = {k: repairs[k] for k in ("plans", "START_IN_COLLISION", *START_REPAIRS)}
    if looks is not None:
        extra["perception"] = perception
        extra["look_errors"] = _look_summary(tally.look_rows, spec.skills)
    if augment:
        extra["augment"] = True
    counts = tally.summary()
    return {"task": task, "variant": variant, "method": method, "profile": profile, "seed": seed, "action_noise": noise,
            "attempts": attempts, "successes": counts["successes"], "rate": counts["successes"] / attempts,
            "wall_seconds": time.perf_counter() - t0, "source_demos": source, **counts, **extra}


def _label(e: dict, a, noise: float) -> None:
    """The entry's experiment settings and the command that reruns it."""
    e["command"] = (f".venv/bin/python bench/datagen/diagnose.py --task {a.task} --variant {a.variant} "
                    f"--attempts {a.attempts} --noise {noise} --seed {a.seed} --profile {a.profile} "
                    f"--method {a.method}" + (f" --touch {a.touch}" if a.touch else "")
                    + (" --stages" if a.stages else "") + (" --augment" if a.augment else "")
                    + (" --mimicgen-offsets {} {}".format(*a.mimicgen_offsets) if a.mimicgen_offsets else "")
                    + (f" --pod-mass {a.pod_mass}" if a.pod_mass else ""))
    if a.pod_mass:
        e["pod_mass"] = a.pod_mass
    e["wrist_backout"] = not a.without_wrist_backout
    e["command"] += " --without-wrist-backout" if a.without_wrist_backout else ""
    e["paper_contacts"] = not a.without_paper_contacts
    e["command"] += " --without-paper-contacts" if a.without_paper_contacts else ""
    e["command"] += f" --perception {a.perception}" if a.perception != "ground_truth" else ""
    e["command"] += f" --bags {a.bags}" if a.bags else ""
    if a.robosuite_joint_limits:
        e["joint_limits"] = "robosuite"
        e["command"] += " --robosuite-joint-limits"
    if a.finger_friction:
        e["finger_friction"] = list(a.finger_friction)
        e["command"] += " --finger-friction {} {}".format(*a.finger_friction)
    if a.perception == "estimate":
        e["look_rule"] = a.look_rule
        e["command"] += f" --look-rule {a.look_rule}"


def _key(x: dict) -> tuple:
    """An entry's identity in the results file (a rerun of the same experiment replaces it)."""
    return (x["task"], x["variant"], x.get("method", "skillgen"), x["action_noise"], x["seed"], x["profile"],
            tuple(x.get("mimicgen_offsets", ())), x.get("augment", False), x.get("pod_mass", 0.0),
            x.get("wrist_backout", True), x.get("paper_contacts", False), x.get("perception", "ground_truth"),
            x.get("look_rule", "latest"),
            tuple(x.get("finger_friction", ())), (x.get("source_demos") or {}).get("sha256"),
            x.get("joint_limits", "urdf"))


def _use_robosuite_joint_limits() -> None:
    """Every scene the sim builds from here on limits the arm's joints to robosuite's ranges (pybullet enforces
    changeDynamics' limits under torque control; getJointInfo keeps reporting the URDF's)."""
    from skillgen_ros.core.robot import ROBOSUITE_Q_LOWER, ROBOSUITE_Q_UPPER
    from skillgen_ros.core.sim.world import SimWorld

    build = SimWorld._build_scene

    def _build_scene(self, poses, objects):
        build(self, poses, objects)
        for j, lo, hi in zip(self.arm, ROBOSUITE_Q_LOWER, ROBOSUITE_Q_UPPER):
            self.p.changeDynamics(self.robot, j, jointLowerLimit=float(lo), jointUpperLimit=float(hi))

    SimWorld._build_scene = _build_scene
    attempt_tally.JOINT_LIMITS = (ROBOSUITE_Q_LOWER, ROBOSUITE_Q_UPPER)


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
    ap.add_argument("--augment", action="store_true", help="skillgen with initiation augmentation (+IA)")
    ap.add_argument("--mimicgen-offsets", type=int, nargs=2, metavar=("LO", "HI"),
                    help="replace the task's MimicGen subtask_term_offset_range (an experiment)")
    ap.add_argument("--pod-mass", type=float, default=0.0, metavar="KG",
                    help="Coffee only: the pod's mass instead of coffee.POD_MASS (an experiment: MimicGen's is 0.007)")
    ap.add_argument("--bags", help="the source demos' folder (default bags/<task>; the entry records its digest)")
    ap.add_argument("--perception", default="ground_truth", choices=["ground_truth", "estimate"],
                    help="estimate: also each look's pose errors against the sim's truth, by outcome")
    ap.add_argument("--without-wrist-backout", action="store_true",
                    help="A/B: the planner without its wrist back-out (start_repair.py, added 2026-12-05)")
    ap.add_argument("--without-paper-contacts", action="store_true",
                    help="A/B: retreat/approach allow only the named objects (before 2026-12-06's paper rule: "
                         "every manipulated object for the hand, anything for the held object)")
    ap.add_argument("--look-rule", default="untouched", choices=["untouched", "latest"],
                    help="estimate, A/B: latest = a movable object takes every look (LookBeliefs before 2026-12-06)")
    ap.add_argument("--finger-friction", type=float, nargs=2, metavar=("LATERAL", "SPINNING"),
                    help="an experiment: the fingers' pybullet friction instead of sim/world.py's (1.5, 0.01)")
    ap.add_argument("--robosuite-joint-limits", action="store_true",
                    help="an experiment: the sim's arm joints limited to robosuite's Panda ranges (core/robot.py "
                         "ROBOSUITE_Q_LOWER / _UPPER) instead of pybullet_data's URDF's; the planner keeps its own")
    a = ap.parse_args(argv)
    if a.robosuite_joint_limits:
        _use_robosuite_joint_limits()
    if a.finger_friction:
        from skillgen_ros.core.sim import world
        world.FINGER_LATERAL_FRICTION, world.FINGER_SPINNING_FRICTION = a.finger_friction
    if a.look_rule == "latest":
        from skillgen_ros.core.generation.grasp import LookBeliefs
        LookBeliefs.KEEP_UNTOUCHED = False
    if a.without_wrist_backout:
        from skillgen_ros.core.planning.start_repair import StartRepairs
        StartRepairs._wrist_clears = staticmethod(lambda q0, allow, collides: False)
    if a.without_paper_contacts:
        from skillgen_ros.core.planning.planner import MotionPlanner
        plan = MotionPlanner.plan
        MotionPlanner.plan = lambda self, *args, **kw: plan(self, *args, **{**kw, "movable": None})
    if a.stages and a.task not in STAGES:
        ap.error(f"--stages knows the stages of {', '.join(STAGES)} only")
    if a.pod_mass:
        _set_pod_mass(a.task, a.pod_mass)
    out = json.loads(OUT.read_text()) if OUT.exists() else {"entries": []}
    out["machine"] = machine_info()
    for noise in a.noise:
        e = diagnose(a.task, a.variant, a.attempts, noise, a.seed, a.profile, a.method, a.touch, a.stages,
                     tuple(a.mimicgen_offsets) if a.mimicgen_offsets else None, a.augment, a.perception,
                     Path(a.bags) if a.bags else None)
        _label(e, a, noise)
        if OUT.exists():  # re-read: another diagnosis may have written its entry since this one started
            out["entries"] = json.loads(OUT.read_text())["entries"]
        out["entries"] = [x for x in out["entries"] if _key(x) != _key(e)] + [e]
        OUT.write_text(json.dumps(out, indent=1) + "\n")
        per = ", ".join(f"{k}: {v['successes']}/{v['attempts']}" for k, v in e["by_source_demo"].items())
        touch = f" | touching {a.touch}: {e['attempts_touching']} ({e['successes_touching']} succeeded)" if a.touch else ""
        touch += f" | stages {e['task_failed_stages']}" if a.stages else ""
        touch += f" | dragging (> {DRAGGED} m) {e['attempts_dragging']} ({e['successes_dragging']} succeeded)"
        touch += f" | slipping in the hand (> {SLIPPED} m) {e['attempts_slipping']} ({e['successes_slipping']} succeeded)"
        touch += f" | failed at {e['failures_at_skill']} | plans {e['plans']}"
        touch += f" | joint on its limit in a skill (attempts, successes) {e['joint_at_limit_in_a_skill']}"
        print(f"{a.task} {a.variant} {a.method}{'+IA' if a.augment else ''} noise {noise}: {e['successes']}/{e['attempts']} | by demo {per}{touch}",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

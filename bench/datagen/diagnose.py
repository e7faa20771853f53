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
from bench.machine import machine_info  # noqa: E402
from skillgen_ros.core.planning.start_repair import START_REPAIRS  # noqa: E402

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


def _coffee_stage(obs: dict) -> str:
    """How far a failed Coffee attempt got, at its last step: which part of coffee.py's `_check_pod` /
    `_check_lid` fails, with the pod's x-y miss from the holder centre (allowed: 5.2 mm) in 5 mm bins."""
    from scipy.spatial.transform import Rotation as R

    from skillgen_ros.core.tasks import coffee as C

    pod, machine = np.asarray(obs["coffee_pod_pose"], float), np.asarray(obs["coffee_machine_pose"], float)
    lid = np.asarray(obs["coffee_machine_joints"], float)[:, 0]
    if pod[:, 2].max() - pod[0, 2] < LIFTED:
        return "1 pod not lifted"
    holder = R.from_quat(machine[-1, 3:]).apply(C.coffee_machine().keypoint("pod_holder")) + machine[-1, :3]
    miss = C.pod_miss(holder, pod[-1])
    if miss > C.POD_MISS_ALLOWED:
        return f"2 pod beside the holder, x-y miss {5 * int(miss * 200)}-{5 * int(miss * 200) + 5} mm"
    if C.pod_below_holder(holder, pod[-1]):
        return "3 pod below the holder's bottom"
    if lid[-1] >= C.LID_CLOSED_TOLERANCE:
        deg = 15 * int(np.degrees(lid[-1]) // 15)
        return f"4 pod in the holder, lid open {deg}-{deg + 15} deg at the end"
    return "5 lid closed, pod on the holder's rim (top above the lid's underside)"


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


STAGES = {"CoffeePreparation": _coffee_prep_stage, "Coffee": _coffee_stage}   # tasks whose failures --stages can place
DRAGGED = 0.02  # m: an object that slid this far across the table before it was first lifted was dragged


def _drags(ep, spec) -> dict[str, float]:
    """Per object that a transit skill grasps and a transfer skill then carries: how far it slid in x-y from
    its grasp skill's first step until it first rose 1 cm above where it was then (to the attempt's end if
    it never rose). A carried object slides ~0; one pulled along the table by the next segment, cm."""
    carried = {getattr(sk, "attached_object", None) for sk in spec.skills if sk.mode == "transfer"}
    skill_of = np.asarray(ep.labels["skill_index"])
    out = {}
    for sk in spec.skills:
        key = f"{sk.object_id}_pose"
        steps = np.flatnonzero(skill_of == sk.index)
        if sk.mode != "transit" or sk.object_id not in carried or key not in ep.obs or not steps.size:
            continue
        p = np.asarray(ep.obs[key], float)[steps[0]:, :3]
        risen = np.flatnonzero(p[:, 2] > p[0, 2] + 0.01)
        before = p[: risen[0] + 1] if risen.size else p
        out[sk.object_id] = float(np.linalg.norm(before[:, :2] - p[0, :2], axis=1).max())
    return out


AT_LIMIT = np.radians(1.0)  # a joint within this of its position limit is on it


def _joints_at_limit(ep) -> list[int]:
    """The arm joints (0-based, panda_joint1 = 0) that reached within 1 deg of a position limit during any
    skill's replay (mp_step == 0): a rigidly transformed skill whose wrist turn runs past panda_joint7's range
    leaves the hand short of its targets."""
    from skillgen_ros.core.robot import Q_LOWER, Q_UPPER

    q = np.asarray(ep.obs["robot0_joint_pos"], float)[np.asarray(ep.labels["mp_step"]) == 0]
    if not len(q):
        return []
    hit = (q <= Q_LOWER + AT_LIMIT) | (q >= Q_UPPER - AT_LIMIT)
    return [int(j) for j in np.flatnonzero(hit.any(axis=0))]


def diagnose(task: str, variant: str, attempts: int, noise: float, seed: int, profile: str,
             method: str = "skillgen", touch: str = "", stages: bool = False,
             mimicgen_offsets: tuple[int, int] | None = None, augment: bool = False,
             perception: str = "ground_truth") -> dict:
    """One cell's attempts, grouped by the source demo of the last skill (the insertion's); with
    `touch`, also how many attempts pushed the robot against that body, and how many of those
    still succeeded (pybullet lets the arm shove past a fixed obstacle and keep its grasp). With
    `mimicgen_offsets`, MimicGen's subtask_term_offset_range is replaced for this run (an experiment on
    where its subtasks end, never a baseline number)."""
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
    demos = load_source_demos(expand_bag_paths([str(ROOT / "bags" / task)]), spec)
    cfg = RunRequest(task=task, variant=variant, method=method, attempts=attempts, seed=seed, profile=profile,
                     action_noise=noise, augment=augment, output_dir="/nonexistent").config()
    env = SimGenerationEnv(SimEnvConfig(perception=perception, seed=seed, video=False))
    by_demo: dict[int, list[int]] = defaultdict(lambda: [0, 0])
    reasons: Counter = Counter()
    at_skill: Counter = Counter()  # failure reason and the last skill whose initiation was planned
    reached: Counter = Counter()
    touching = _count_touches(env, touch) if touch else None
    repairs = _count_start_repairs(env)
    looks = _record_look_errors(env) if perception == "estimate" else None
    look_rows: list[tuple[bool, list]] = []
    touched = [0, 0]  # attempts touching `touch`, and how many of them succeeded
    drags: dict[str, list[float]] = defaultdict(list)
    at_limit: dict[str, list[int]] = defaultdict(lambda: [0, 0])  # joint -> attempts on its limit, successes
    dragged = [0, 0]  # attempts dragging an object, and how many of them succeeded
    t0 = time.perf_counter()
    try:
        for i in range(attempts):
            if touching:
                touching[0] = 0
            if looks is not None:
                looks.clear()
            r = run_attempt(env, demos, spec, method, i, seed, cfg)
            look_rows.append((bool(r.success), list(looks) if looks is not None else []))
            if touching and touching[0] > 0:
                touched[0] += 1
                touched[1] += int(r.success)
            moved = _drags(r.episode, spec) if r.episode is not None else {}
            for k, v in moved.items():
                drags[k].append(v)
            if any(v > DRAGGED for v in moved.values()):
                dragged[0] += 1
                dragged[1] += int(r.success)
            for j in _joints_at_limit(r.episode) if r.episode is not None else []:
                at_limit[f"panda_joint{j + 1}"][0] += 1
                at_limit[f"panda_joint{j + 1}"][1] += int(r.success)
            d = int(r.source_demos[-1]) if r.source_demos else -1
            by_demo[d][0] += int(r.success)
            by_demo[d][1] += 1
            if not r.success:
                reasons[f"{r.reason.value}: {r.message[:80]}"] += 1
                if r.initiation_candidates_used:
                    at_skill[f"{r.reason.value} at skill {len(r.initiation_candidates_used) - 1}"] += 1
                if stages and r.reason.value == "TASK_FAILED":
                    reached[STAGES[task](r.episode.obs)] += 1
    finally:
        env.close()
        mg.MIMICGEN_SPECS.clear()
        mg.MIMICGEN_SPECS.update(specs_before)
    n_ok = sum(v[0] for v in by_demo.values())
    extra = {"touch": touch, "attempts_touching": touched[0], "successes_touching": touched[1]} if touch else {}
    if stages:
        extra["task_failed_stages"] = dict(sorted(reached.items()))
    if mimicgen_offsets:
        extra["mimicgen_offsets"] = list(mimicgen_offsets)
    extra["drag_measure"] = "from the grasp skill's first step"   # entries without it measured from step 0
    extra["drag_m"] = {k: {"median": float(np.median(v)), "p90": float(np.percentile(v, 90)), "n": len(v)}
                       for k, v in drags.items()}
    extra["attempts_dragging"], extra["successes_dragging"] = dragged
    extra["joint_at_limit_in_a_skill"] = {k: {"attempts": v[0], "successes": v[1]} for k, v in sorted(at_limit.items())}
    extra["plans"] = {k: repairs[k] for k in ("plans", "START_IN_COLLISION", *START_REPAIRS)}
    if looks is not None:
        extra["perception"] = perception
        extra["look_errors"] = _look_summary(look_rows, spec.skills)
    extra["successful_indices"] = [i for i, (ok, _) in enumerate(look_rows) if ok]
    if augment:
        extra["augment"] = True
    return {"task": task, "variant": variant, "method": method, "profile": profile, "seed": seed, "action_noise": noise,
            "attempts": attempts, "successes": n_ok, "rate": n_ok / attempts,
            "by_source_demo": {str(k): {"successes": v[0], "attempts": v[1]} for k, v in sorted(by_demo.items())},
            "failures": dict(reasons.most_common()), "failures_at_skill": dict(sorted(at_skill.items())),
            "wall_seconds": time.perf_counter() - t0, **extra}


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
    ap.add_argument("--perception", default="ground_truth", choices=["ground_truth", "estimate"],
                    help="estimate: also each look's pose errors against the sim's truth, by outcome")
    ap.add_argument("--without-wrist-backout", action="store_true",
                    help="A/B: the planner without its wrist back-out (start_repair.py, added 2026-12-05)")
    ap.add_argument("--look-rule", default="untouched", choices=["untouched", "latest"],
                    help="estimate, A/B: latest = a movable object takes every look (LookBeliefs before 2026-12-06)")
    ap.add_argument("--finger-friction", type=float, nargs=2, metavar=("LATERAL", "SPINNING"),
                    help="an experiment: the fingers' pybullet friction instead of sim/world.py's (1.5, 0.01)")
    a = ap.parse_args(argv)
    if a.finger_friction:
        from skillgen_ros.core.sim import world
        world.FINGER_LATERAL_FRICTION, world.FINGER_SPINNING_FRICTION = a.finger_friction
    if a.look_rule == "latest":
        from skillgen_ros.core.generation.grasp import LookBeliefs
        LookBeliefs.KEEP_UNTOUCHED = False
    if a.without_wrist_backout:
        from skillgen_ros.core.planning.start_repair import StartRepairs
        StartRepairs._wrist_clears = staticmethod(lambda q0, allow, collides: False)
    if a.stages and a.task not in STAGES:
        ap.error(f"--stages knows the stages of {', '.join(STAGES)} only")
    if a.pod_mass:
        _set_pod_mass(a.task, a.pod_mass)
    out = json.loads(OUT.read_text()) if OUT.exists() else {"entries": []}
    out["machine"] = machine_info()
    for noise in a.noise:
        e = diagnose(a.task, a.variant, a.attempts, noise, a.seed, a.profile, a.method, a.touch, a.stages,
                     tuple(a.mimicgen_offsets) if a.mimicgen_offsets else None, a.augment, a.perception)
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
        e["command"] += f" --perception {a.perception}" if a.perception != "ground_truth" else ""
        if a.finger_friction:
            e["finger_friction"] = list(a.finger_friction)
            e["command"] += " --finger-friction {} {}".format(*a.finger_friction)
        if a.perception == "estimate":
            e["look_rule"] = a.look_rule
            e["command"] += f" --look-rule {a.look_rule}"

        def key(x):
            return (x["task"], x["variant"], x.get("method", "skillgen"), x["action_noise"], x["seed"], x["profile"],
                    tuple(x.get("mimicgen_offsets", ())), x.get("augment", False), x.get("pod_mass", 0.0),
                    x.get("wrist_backout", True), x.get("perception", "ground_truth"), x.get("look_rule", "latest"),
                    tuple(x.get("finger_friction", ())))
        if OUT.exists():  # re-read: another diagnosis may have written its entry since this one started
            out["entries"] = json.loads(OUT.read_text())["entries"]
        out["entries"] = [x for x in out["entries"] if key(x) != key(e)] + [e]
        OUT.write_text(json.dumps(out, indent=1) + "\n")
        per = ", ".join(f"{k}: {v['successes']}/{v['attempts']}" for k, v in e["by_source_demo"].items())
        touch = f" | touching {a.touch}: {e['attempts_touching']} ({e['successes_touching']} succeeded)" if a.touch else ""
        touch += f" | stages {e['task_failed_stages']}" if a.stages else ""
        touch += f" | dragging (> {DRAGGED} m) {e['attempts_dragging']} ({e['successes_dragging']} succeeded)"
        touch += f" | failed at {e['failures_at_skill']} | plans {e['plans']}"
        touch += f" | joint on its limit in a skill (attempts, successes) {e['joint_at_limit_in_a_skill']}"
        print(f"{a.task} {a.variant} {a.method}{'+IA' if a.augment else ''} noise {noise}: {e['successes']}/{e['attempts']} | by demo {per}{touch}",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

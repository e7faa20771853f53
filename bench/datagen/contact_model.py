"""bench/datagen/contact_model.py: is pybullet's contact model why Threading falls short of the paper?

Failed Threading attempts end with the shaft stopped at the ring (MimicGen's 3 mm a side) and the needle
turned in the hand by 10-25 deg. This changes one part of the contact model at a time and compares, on
the same reset seeds, with the paper profile and its action noise (0.05), as bench/datagen:

- `stock`: the sim as it is, with the shipped source demos (bags/<task>);
- `pads`: robosuite's Panda finger pads (SimConfig.finger_pads, core/sim/contact_model.py: panda_gripper.xml's
  `finger1_pad_collision`, half size 0.008 x 0.004 x 0.008, its face 0.5 mm proud of the finger) added to
  pybullet_data's panda.urdf, whose grip is the convex finger meshes alone, and without that URDF's soft finger
  contact; its source demos are remade on that model (`skillgen demos make`) in out/contact_model/, so the
  demos' grasps are the pads' grasps (`pads+iterations:200` is core's `robosuite_pads` contact model);
- `ring:K`: the tripod's contacts compliant, pybullet contactStiffness K N/m and critical-ish damping
  2 sqrt(K) (MuJoCo's default solref gives the ring a soft contact; robosuite's ring_tripod.py keeps it);
- `mass:OBJECT:F`: that object F times as heavy (the needle is 7.6 g at MimicGen's density, in a hand of
  ~1 kg: the mass ratio pybullet's solver handles worst; our nuts are 50 g where robosuite's density-100 nuts
  are 15.8 g (square) and 19.4 g (round));
- `hz:H`, `iterations:N`: pybullet's time step 1/H s (ours 240 Hz; robosuite steps MuJoCo at 500 Hz) or its
  solver's iteration count (ours 50);
- `A+B`: changes together (e.g. `pads+mass:needle:10`).

Per arm and seed: successes, and how far the carried object turned in the hand (the angle of T_ee_object's
change) over the planned transfer and over the skill that follows. An experiment on the sim, never a
benchmark cell.

    .venv/bin/python bench/datagen/contact_model.py --task Threading --variant D0 --attempts 40 \
        --seeds 1000 2000 --arms stock pads ring:300 mass:needle:10

Writes bench/results/contact_model.json (one entry per task, variant, arm and noise).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.machine import machine_info  # noqa: E402

OUT = ROOT / "bench" / "results" / "contact_model.json"
WORK = ROOT / "out" / "contact_model"
SIM_SETTINGS = {"hz": "physics_hz", "iterations": "solver_iterations"}  # arm kind -> SimConfig field
SCALED = ("ring", "mass", *SIM_SETTINGS)  # the kinds that take a value (pads: SimConfig.finger_pads)


def parse_arm(arm: str) -> list[tuple[str, str, float]]:
    """[(kind, object id, value)] of an arm name: stock, pads, ring:<N/m> (the tripod), mass:<object>:<factor>,
    or several changes joined by '+' (e.g. pads+mass:needle:10)."""
    out = []
    for part in arm.split("+"):
        kind, _, rest = part.partition(":")
        target, _, value = rest.rpartition(":") if kind == "mass" else ("tripod" if kind == "ring" else "", "", rest)
        try:
            x = float(value) if kind in SCALED else 0.0
        except ValueError:
            x = -1.0
        if not (kind in ("stock", "pads") and not rest or kind in SCALED and x > 0 and (target or kind in SIM_SETTINGS)
                and (kind != "hz" or x % 20 == 0)):
            raise SystemExit(f"unknown arm {arm!r}: stock, pads, ring:<N/m>, mass:<object>:<factor>, "
                             "hz:<multiple of 20>, iterations:<n>, joined by '+'")
        out.append((kind, target, x))
    return out


def use_model(arm: str) -> None:
    """Point the sim at the arm's model (before the arm's worlds are built)."""
    from skillgen_ros.core.sim import world

    changes = parse_arm(arm)
    world.SimWorld._spawn = stock = _STOCK.setdefault("spawn", world.SimWorld._spawn)
    world.SimWorld.__init__ = init = _STOCK.setdefault("init", world.SimWorld.__init__)
    settings = {SIM_SETTINGS[k]: (int(x) if k == "iterations" else x) for k, _, x in changes if k in SIM_SETTINGS}
    if any(kind == "pads" for kind, _, _ in changes):
        settings["finger_pads"] = True  # core/sim/contact_model.py's pads (robosuite_pads without its iterations)
    if settings:
        def init_with(self, config=None, gui=False, **overrides):
            init(self, config, gui, **{**overrides, **settings})
        world.SimWorld.__init__ = init_with

    if any(kind in ("ring", "mass") for kind, _, _ in changes):
        def spawn(self, o, pose):
            body = stock(self, o, pose)
            for kind, target, x in changes:
                if kind == "ring" and o.id == target:
                    for link in range(-1, self.p.getNumJoints(body)):
                        self.p.changeDynamics(body, link, contactStiffness=x, contactDamping=2 * np.sqrt(x))
                elif kind == "mass" and o.id == target:  # the inertia scales with the mass (same shape, denser)
                    inertia = np.asarray(self.p.getDynamicsInfo(body, -1)[2]) * x
                    self.p.changeDynamics(body, -1, mass=o.mass * x, localInertiaDiagonal=inertia.tolist())
            return body
        world.SimWorld._spawn = spawn


_STOCK: dict = {}  # the sim's own SimWorld._spawn and __init__, kept at the first use_model()


def turned_in_hand(ep, object_id: str, first_skill: int) -> tuple[float, float] | None:
    """Degrees the object turned in the hand from the end of `first_skill`'s replay to the start of the next
    skill's (the planned transfer), and over that next skill's replay; None if the attempt never got there."""
    from scipy.spatial.transform import Rotation as R

    skill, mp = np.asarray(ep.labels["skill_index"]), np.asarray(ep.labels["mp_step"])
    a, b = np.flatnonzero((skill == first_skill) & (mp == 0)), np.flatnonzero((skill == first_skill + 1) & (mp == 0))
    if not (a.size and b.size):
        return None
    hand = R.from_quat(np.asarray(ep.obs["robot0_eef_quat"], float))
    obj = R.from_quat(np.asarray(ep.obs[f"{object_id}_pose"], float)[:, 3:])

    def angle(i: int, j: int) -> float:
        return float(np.degrees(((hand[i].inv() * obj[i]).inv() * (hand[j].inv() * obj[j])).magnitude()))
    return angle(a[-1], b[0]), angle(b[0], b[-1])


def run_arm(arm: str, task: str, variant: str, seeds: list[int], attempts: int, noise: float) -> dict:
    """One arm's attempts on every seed: successes and the in-hand turn of the first transfer's object."""
    from skillgen_ros.core.generation.attempt import run_attempt
    from skillgen_ros.core.generation.session import RunRequest
    from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv
    from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos
    from skillgen_ros.core.tasks import get_task

    spec = get_task(task)
    for _, target, _ in parse_arm(arm):
        if target and target not in {o.id for o in spec.objects}:
            raise SystemExit(f"arm {arm!r}: {task} has no object {target!r}")
    use_model(arm)
    bags = ROOT / "bags" / task
    if "pads" in arm.split("+"):  # the demos' own grasps on the pads
        from skillgen_ros.cli.main import main as cli
        if cli(["demos", "make", "--task", task, "--out", str(WORK / "bags"), "--force"]) != 0:
            raise SystemExit(f"could not make {task}'s demos on the pads model")
        bags = WORK / "bags" / task
    demos = load_source_demos(expand_bag_paths([str(bags)]), spec)
    moved = next(sk for sk in spec.skills if sk.mode == "transfer")
    out = {"arm": arm, "source_demos": str(bags.relative_to(ROOT)), "seeds": {}}
    for seed in seeds:
        cfg = RunRequest(task=task, variant=variant, method="skillgen", attempts=attempts, seed=seed,
                         profile="paper", action_noise=noise, output_dir="/nonexistent").config()
        env = SimGenerationEnv(SimEnvConfig(perception="ground_truth", seed=seed, video=False))
        rows = []
        t0 = time.perf_counter()
        try:
            for i in range(attempts):
                r = run_attempt(env, demos, spec, "skillgen", i, seed, cfg)
                turn = turned_in_hand(r.episode, moved.attached_object, moved.index - 1) if r.episode else None
                rows.append((bool(r.success), turn))
        finally:
            env.close()
        out["seeds"][str(seed)] = _summary(rows, attempts, time.perf_counter() - t0)
        print(f"  {arm} seed {seed}: {out['seeds'][str(seed)]['successes']}/{attempts}", flush=True)
    out["successes"] = sum(s["successes"] for s in out["seeds"].values())
    out["attempts"] = attempts * len(seeds)
    return out


def _summary(rows, attempts: int, seconds: float) -> dict:
    def stats(vals):
        return {"n": len(vals), "median": float(np.median(vals)), "p90": float(np.percentile(vals, 90))} if vals else {"n": 0}
    s = {"successes": sum(ok for ok, _ in rows), "attempts": attempts, "wall_seconds": seconds}
    for label, want in (("succeeded", True), ("failed", False)):
        turns = [t for ok, t in rows if ok == want and t is not None]
        s[f"turn_deg_transfer_{label}"] = stats([t[0] for t in turns])
        s[f"turn_deg_skill_{label}"] = stats([t[1] for t in turns])
    return s


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", default="Threading")
    ap.add_argument("--variant", default="D0")
    ap.add_argument("--attempts", type=int, default=40)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1000, 2000])
    ap.add_argument("--noise", type=float, default=0.05)
    ap.add_argument("--arms", nargs="+", default=["stock", "pads"],
                    help="stock, pads, ring:<contact stiffness N/m>, mass:<object>:<factor>, or several joined by '+'")
    a = ap.parse_args(argv)
    for arm in a.arms:  # every name checked before the first arm runs
        parse_arm(arm)
    out = json.loads(OUT.read_text()) if OUT.exists() else {"entries": []}
    for arm in a.arms:
        e = {"task": a.task, "variant": a.variant, "profile": "paper", "action_noise": a.noise,
             **run_arm(arm, a.task, a.variant, a.seeds, a.attempts, a.noise),
             "command": (f".venv/bin/python bench/datagen/contact_model.py --task {a.task} --variant {a.variant} "
                         f"--attempts {a.attempts} --seeds {' '.join(map(str, a.seeds))} --noise {a.noise} --arms {arm}")}
        key = (e["task"], e["variant"], e["arm"], e["action_noise"])
        out["entries"] = [x for x in out["entries"]
                          if (x["task"], x["variant"], x["arm"], x["action_noise"]) != key] + [e]
        out["machine"] = machine_info()
        OUT.write_text(json.dumps(out, indent=1) + "\n")
        print(f"{a.task} {a.variant} {arm}: {e['successes']}/{e['attempts']}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""`skillgen demos`: make the shipped source demos, or record one by teleoperation.

    skillgen demos make --task Square [--task ...|all] [--n 10] [--subset 3] [--out bags] [--force]
                        [--contact-model pybullet|robosuite_pads]
    skillgen demos record --task Square [--seed 0] [--out recordings] [--keep-failed]

`make` runs the scripted demonstrator (core/demonstrator: it exists only for this) on the
pybullet SimWorld in-process, on the task's D0 scenes with scene seeds 1000, 1001, ...; a demo
the sim judges failed is redone in the same scene with a new demonstrator seed, as a person would.
Each demo becomes bags/<task>/demo_XX/ (rosbag2-layout MCAP, zstd) with the scene as MCAP
metadata and an auto-annotation sidecar annotations.yaml; bags/<task>/subsets.yaml lists the
demos and the 3-demo subset (min(3, n) by default). `record` starts sim_driver (reset to the
task's scene), the recorder into recordings/<task>/teleop_<UTC>/ (not bags/<task>/, which
`skillgen generate` reads: an unannotated recording there would break it) and the keyboard
teleop in this terminal with its status line (docs/teleop.md). On `q` it runs the task's
success rule on the recorded demo and prints the verdict; a failed demo is moved to
recordings/<task>/failed/ unless `--keep-failed`. A demo is used only once annotated.
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

import yaml

from skillgen_ros.core.errors import InvalidInputError, SkillGenError
from skillgen_ros.core.sim.contact_model import CONTACT_MODELS, DEFAULT_CONTACT_MODEL, contact_settings
from skillgen_ros.core.tasks import TASK_NAMES, get_task

SCENE_SEED_BASE = 1000
MAX_ATTEMPTS = 6
SUBSETS_FILE = "subsets.yaml"
DEFAULT_N = 10  # demos per task: the paper's count
DEFAULT_SUBSET = 3  # the paper's small source-demo subset; capped at --n
MAKE_OUT = "bags"  # where the shipped source demos live (and `skillgen generate` reads by default)
RECORD_OUT = "recordings"  # teleop recordings: their own folder until annotated and chosen
FAILED_DIR = "failed"  # recordings/<task>/failed/: demos whose success check failed


def demonstrator_seed(scene_seed: int, attempt: int) -> int:
    return scene_seed * 100 + attempt


def make_demo(world, task: str, index: int, out_dir: Path, variant: str = "D0",
              max_attempts: int = MAX_ATTEMPTS) -> dict:
    """Record one successful demo into out_dir/demo_<index>/ and annotate it; returns its listing row."""
    from skillgen_ros.cli.annotate import propose, rules_for
    from skillgen_ros.cli.demo_bag import write_demo_bag
    from skillgen_ros.core.demonstrator import ScriptedDemonstrator
    from skillgen_ros.core.skills.annotation import save_annotation
    from skillgen_ros.core.skills.bag_demos import annotation_path

    scene_seed = SCENE_SEED_BASE + index
    name = f"demo_{index:02d}"
    for attempt in range(max_attempts):
        seed = demonstrator_seed(scene_seed, attempt)
        rollout = ScriptedDemonstrator(task, seed).run(world, variant, scene_seed)
        if rollout.success:
            break
    else:
        raise SkillGenError(f"{task} {name}: demonstrator failed {max_attempts} times in scene seed {scene_seed}",
                            "DEMO_FAILED")
    path = out_dir / name
    tmp = out_dir / ".writing" / name  # same name: the bag's files are named after its directory
    shutil.rmtree(tmp, ignore_errors=True)
    write_demo_bag(tmp, rollout)
    if path.exists():
        shutil.rmtree(path)
    tmp.rename(path)
    tmp.parent.rmdir()
    ann = propose(path, get_task(task), rules_for(task))
    save_annotation(str(annotation_path(path)), ann)
    return {"name": name, "scene_seed": scene_seed, "demonstrator_seed": seed, "attempts": attempt + 1,
            "steps": len(rollout.steps), "duration_s": round(rollout.steps[-1].time, 2)}


def make(tasks, n: int, subset: int, out: Path, force: bool, variant: str = "D0",
         contact_model: str = DEFAULT_CONTACT_MODEL) -> int:
    from skillgen_ros.core.sim import SimWorld

    settings = contact_settings(contact_model)
    for task in tasks:  # check every argument before the (slow) sim starts
        get_task(task)
        d = out / task
        if d.exists() and any(d.iterdir()) and not force:
            raise InvalidInputError(f"{d} already holds demos; pass --force to remake them", "EXISTS")
    world = SimWorld(**settings)
    try:
        for task in tasks:
            d = out / task
            d.mkdir(parents=True, exist_ok=True)
            rows = []
            t0 = time.monotonic()
            for i in range(n):
                row = make_demo(world, task, i, d, variant)
                rows.append(row)
                print(f"{task} {row['name']}: {row['steps']} steps, attempt {row['attempts']}", flush=True)
            doc = {"task": task, "variant": variant, "made_by": "skillgen demos make (scripted demonstrator)",
                   "contact_model": contact_model,
                   "demos": rows, "subsets": {"all": [r["name"] for r in rows],
                                              f"first{subset}": [r["name"] for r in rows[:subset]]}}
            (d / SUBSETS_FILE).write_text(yaml.safe_dump(doc, sort_keys=False))
            size = sum(p.stat().st_size for p in d.rglob("*") if p.is_file())
            print(f"{task}: {n} demos in {d} ({size / 1024:.0f} KiB) in {time.monotonic() - t0:.0f} s")
    finally:
        world.close()
    return 0


def subset_paths(task_dir, subset: str = "all") -> list[Path]:
    """Bag paths of a named subset listed in <task_dir>/subsets.yaml (e.g. 'all', 'first3')."""
    task_dir = Path(task_dir)
    f = task_dir / SUBSETS_FILE
    try:
        doc = yaml.safe_load(f.read_text())
    except (OSError, yaml.YAMLError) as e:
        raise InvalidInputError(f"{f}: cannot read the subset listing: {e}", "BAD_SUBSETS") from e
    subsets = doc.get("subsets") or {}
    if subset not in subsets:
        raise InvalidInputError(f"{f}: no subset {subset!r}; known: {sorted(subsets)}", "BAD_SUBSETS")
    return [task_dir / name for name in subsets[subset]]


# ---------------------------------------------------------------------------------------- record
def record_topics() -> list[str]:
    """What `record` records: every topic the source-demo loader reads (core/skills/bag_demos.py), so a
    teleop demo is judged and loaded like a made one (Coffee's lid angle is object_joint_states). On
    the sim that is the ground-truth object poses; on a real robot remap or record
    perception/object_poses instead (the loader prefers it when present)."""
    from skillgen_ros.core.skills.bag_demos import SOURCE_TOPICS

    return list(SOURCE_TOPICS)


def _exe(name: str) -> str:
    return str(Path(sys.prefix) / "bin" / name)


def record(task: str, seed: int, out: Path, variant: str = "D0", keep_failed: bool = False) -> int:
    """sim_driver + recorder + teleop (foreground); on quit, stop all, write the scene sidecar and
    judge the demo (file_recording)."""
    from skillgen_ros import rosenv
    from skillgen_ros.cli.node_logs import NodeLogs

    get_task(task)
    stamp = datetime.now(timezone.utc).strftime("%Y%m%dT%H%M%S")
    bag = out / task / f"teleop_{stamp}"
    bag.parent.mkdir(parents=True, exist_ok=True)
    env = rosenv.ros_environment(dict(__import__("os").environ))
    logs = NodeLogs(out / task / "logs" / bag.name)  # the terminal is the teleop's: other nodes log to files

    def start(name: str, args: list[str]) -> subprocess.Popen:
        with logs.open(name) as f:
            return subprocess.Popen([_exe(name), "--ros-args", *args], env=env, stdin=subprocess.DEVNULL,
                                    stdout=f, stderr=subprocess.STDOUT)
    # lockstep: the sim advances one control period per osc_target, so the recorded command stream
    # is exactly the demo's control steps (and replays open-loop)
    procs = [start("sim_driver", ["-p", f"initial_task:={task}", "-p", f"initial_variant:={variant}",
                                  "-p", f"initial_seed:={seed}", "-p", "timing_mode:=lockstep",
                                  "-p", "publish_points:=false"])]
    try:
        topics = "[" + ",".join(f'"{t}"' for t in record_topics()) + "]"
        # scene: /tf, the robot model and object markers too, so the demo opens as a 3D scene in Foxglove
        procs.append(start("recorder", ["-p", f"output:={bag}", "-p", f"topics:={topics}", "-p", "scene:=true"]))
        print(f"recording {task}/{variant} seed {seed} into {bag} (node logs in {logs.dir}); keys and where "
              f"to grasp: docs/teleop.md (q quits and judges the demo); cameras: `skillgen view` in another "
              f"terminal, Foxglove layout docs/foxglove/teleop.json",
              flush=True)
        # the robot waits for the recorder (and the driver) on osc_target: a bag from the demo's first command
        teleop = subprocess.run([_exe("teleop"), "--ros-args", "-p", f"task:={task}", "-p", "min_subscribers:=2"],
                                env=env)  # this terminal
    except KeyboardInterrupt:
        teleop = None
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.send_signal(2)
                try:
                    p.wait(15)
                except subprocess.TimeoutExpired:
                    p.kill()
        logs.close()
    if bag.is_dir():
        from skillgen_ros.core.skills.bag_demos import SIDECAR_SCENE

        (bag / SIDECAR_SCENE).write_text(yaml.safe_dump({"task": task, "variant": variant, "seed": seed,
                                                         "demo": bag.name, "made_by": "teleop"}))
        file_recording(bag, task, keep_failed)
    else:
        print(f"no demo was recorded (the recorder wrote no {bag}); its log: {logs.path('recorder')}")
    return 0 if teleop is None or teleop.returncode in (0, 130) else 1


def file_recording(bag: Path, task: str, keep_failed: bool = False) -> tuple[bool, Path]:
    """Run the task's success rule on a finished recording, print the verdict, and move a failed demo
    to <task dir>/failed/ (out of the folder demos are taken from) unless keep_failed. Returns
    (success, where the bag is now)."""
    from skillgen_ros.core.teleop import demo_verdict

    try:
        v = demo_verdict(bag, get_task(task))
        ok, detail = v.success, v.detail
    except SkillGenError as e:  # e.g. q pressed before the first command: nothing to judge
        ok, detail = False, str(e)
    print(f"task success: {'YES' if ok else 'NO'} ({detail})", flush=True)
    if ok or keep_failed:
        if not ok:
            print(f"kept the failed demo in {bag} (--keep-failed)")
        print(f"wrote {bag}; next: skillgen annotate {bag} --task {task}")
        return ok, bag
    dest = bag.parent / FAILED_DIR / bag.name
    dest.parent.mkdir(parents=True, exist_ok=True)
    shutil.move(str(bag), str(dest))
    print(f"moved the failed demo to {dest}, out of {bag.parent}; record again, or pass --keep-failed "
          f"to keep failed demos where they were recorded")
    return ok, dest


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="skillgen demos", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("make", help="make source demos with the scripted demonstrator (pybullet)")
    m.add_argument("--task", action="append", required=True,
                   help=f"task to make demos for, one of {list(TASK_NAMES)} or 'all' (repeatable)")
    m.add_argument("--n", type=int, default=DEFAULT_N, help=f"demos per task (default {DEFAULT_N}, the paper's count)")
    m.add_argument("--subset", type=int, default=None,
                   help=f"size of the small subset listed in subsets.yaml (default min({DEFAULT_SUBSET}, n))")
    m.add_argument("--variant", default="D0", help="reset distribution of the demo scenes (default D0, the paper's)")
    m.add_argument("--out", default=MAKE_OUT, help=f"folder for <task>/demo_XX/ (default {MAKE_OUT})")
    m.add_argument("--force", action="store_true", help="remake demos that already exist")
    m.add_argument("--contact-model", default=DEFAULT_CONTACT_MODEL, choices=sorted(CONTACT_MODELS),
                   help=f"the sim's contact model (core/sim/contact_model.py; default {DEFAULT_CONTACT_MODEL}); "
                        "generation on a model needs demos made on it")
    r = sub.add_parser("record", help="record one demo by keyboard teleoperation on the sim")
    r.add_argument("--task", required=True, help=f"task to demonstrate, one of {list(TASK_NAMES)}")
    r.add_argument("--seed", type=int, default=0, help="scene seed: where the objects start (default 0)")
    r.add_argument("--variant", default="D0", help="reset distribution of the scene (default D0)")
    r.add_argument("--out", default=RECORD_OUT,
                   help=f"folder for <task>/teleop_<UTC time>/ (default {RECORD_OUT}; not bags/, which "
                        "generation reads)")
    r.add_argument("--keep-failed", action="store_true",
                   help=f"keep a demo that fails the task's success check where it was recorded (default: "
                        f"move it to <out>/<task>/{FAILED_DIR}/)")
    return p


def main(argv: list[str] | None = None) -> int:
    a = _parser().parse_args(argv)
    if a.cmd == "make":
        tasks = list(TASK_NAMES) if "all" in a.task else a.task
        subset = min(DEFAULT_SUBSET, a.n) if a.subset is None else a.subset
        if a.n < 1 or not 1 <= subset <= a.n:
            raise InvalidInputError(f"--n must be >= 1 and --subset in [1, n], got {a.n}, {subset}",
                                    "BAD_ARGUMENTS")
        return make(tasks, a.n, subset, Path(a.out), a.force, a.variant, a.contact_model)
    return record(a.task, a.seed, Path(a.out), a.variant, a.keep_failed)


if __name__ == "__main__":
    sys.exit(main())

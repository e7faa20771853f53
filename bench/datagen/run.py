"""bench/datagen: generation success per task/variant/method/profile, throughput, graph overhead, perception cost.

Cells: every task variant (core/tasks) x method (skillgen, mimicgen, skillgen+IA) under the `paper`
algorithm profile (core/generation/profile.py: the paper's Algorithm 1), and skillgen, skillgen+IA
again under `skillgen_ros` (ours: initiation candidates, release moves, planner start repairs,
collision filter) as their own columns. MimicGen and Replay-Noise have nothing a profile changes:
they run once (recorded under `paper`). Every method and profile of a cell uses the same seed, so the
same scenes. Each finished cell is written to the JSON at once; a rerun skips cells already there
with the same attempts and seed from the same source demos (resumable; --force reruns them; a cell whose
demos were remade since runs again: bench/datagen/source_digest.py). Each cell records its profile, its
source demos' digest and the initiation candidates its attempts used.

Full protocol (about 2 h on 2 cores; see the README for the last measured duration):
    .venv/bin/python bench/datagen/run.py --attempts 200 --workers 2
Smoke (minutes): two cells, both profiles, all methods, into its own JSON:
    .venv/bin/python bench/datagen/run.py --attempts 10 --workers 2 --tasks Square Threading --variants D0 D1 \
        --skip-extras --out bench/results/datagen_smoke.json
Only some cells again (the others and the extras stay as they are in the JSON):
    .venv/bin/python bench/datagen/run.py --attempts 200 --workers 2 --methods skillgen+IA --profiles paper --force
A new task's smoke (ThreePieceAssembly, 20 attempts a cell, paper profile) into its own JSON:
    .venv/bin/python bench/datagen/run.py --attempts 20 --workers 2 --tasks ThreePieceAssembly \
        --methods skillgen mimicgen --profiles paper --skip-extras --out bench/results/datagen_smoke_three_piece.json
Coffee's smoke (20 attempts a cell, paper profile, ground truth; about 11 min on 2 shared cores):
    .venv/bin/python bench/datagen/run.py --attempts 20 --workers 2 --tasks Coffee \
        --methods skillgen mimicgen --profiles paper --skip-extras --out bench/results/datagen_smoke_coffee.json
One extra part again, updating the JSON in place (e.g. the graph overhead: 3 pairs of 50 attempts):
    .venv/bin/python bench/datagen/run.py --only graph_overhead
    # every task's D0 through the ROS graph beside the same attempts in-process (estimated poses, 20 each)
    .venv/bin/python bench/datagen/run.py --only graph_rates
    # some tasks again, the others' entries kept (each task records its own rerun command and date)
    .venv/bin/python bench/datagen/run.py --only graph_rates --tasks CoffeePreparation
The D0 cells on other seeds, each into its own JSON (a check that a cell's gap to the paper is not noise):
    for s in 2000 3000 4000; do .venv/bin/python bench/datagen/run.py --workers 2 --seed $s --skip-extras \
        --tasks Square NutAssembly --variants D0 --methods skillgen --out bench/results/datagen_seed$s.json; done
An A/B of the planned motions' speed (cells only; a separate JSON so the table stays one setting):
    .venv/bin/python bench/datagen/run.py --seed 3000 --tasks NutAssembly --variants D0 --methods skillgen \
        --velocity-scale 1.0 --skip-extras --out bench/results/datagen_vs10_seed3000.json
The paper's Square, Threading and Nut Assembly cells on robosuite's finger pads (core/sim/contact_model.py),
cells only, into their own JSON (the model's source demos are made in out/demos/robosuite_pads/ first):
    .venv/bin/python bench/datagen/run.py --attempts 200 --workers 2 --tasks Square Threading NutAssembly \
        --variants D0 D1 D2 --methods skillgen mimicgen --profiles paper --contact-model robosuite_pads \
        --skip-extras --out bench/results/datagen_robosuite_pads.json

Success cells run in-process (SimGenerationEnv: the same Algorithm 1, dataset writer and seeds as
the datagen node) with fixed seeds; the graph-overhead cell runs the same attempts through the
ROS graph (sim_driver lockstep, perception, planner, skill_replay, datagen) and in-process, in
the same run, and reports the ratio. Throughput is successful demos per hour per CPU core, from
the CPU time of the process that ran the cell. Aggregates: bench/datagen/summary.py.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.datagen import source_digest  # noqa: E402
from bench.datagen.summary import PROFILE_FREE, cell_key, summarize  # noqa: E402
from bench.machine import machine_info  # noqa: E402

from skillgen_ros.core.sim.contact_model import CONTACT_MODELS, DEFAULT_CONTACT_MODEL  # noqa: E402
from skillgen_ros.core.tasks import TASK_NAMES as TASKS  # noqa: E402  (the one task list)
METHODS = [("skillgen", False), ("mimicgen", False), ("skillgen", True)]
PROFILES = ("paper", "skillgen_ros")
DEFAULT_OUT = ROOT / "bench" / "results" / "datagen.json"


def task_variants(task: str) -> list[str]:
    """A task's variants as the task suite defines them (core/tasks/suite.py), so renamed or added
    variants (e.g. Square's D1_clutter / D2_clutter) are benchmarked without editing this file."""
    from skillgen_ros.core.tasks import get_task

    return list(get_task(task).variants)


def source_demo_dir(task: str, contact_model: str = DEFAULT_CONTACT_MODEL) -> Path:
    """Where a contact model's source demos are: the shipped bags/<task> on the default model, else demos
    made on that model (`skillgen demos make --contact-model`) in out/demos/<model>/<task>, made on first use."""
    if contact_model == DEFAULT_CONTACT_MODEL:
        return ROOT / "bags" / task
    d = ROOT / "out" / "demos" / contact_model
    listing = d / task / "subsets.yaml"
    if not listing.exists():
        from skillgen_ros.cli.demos import DEFAULT_N, DEFAULT_SUBSET, make

        make([task], DEFAULT_N, DEFAULT_SUBSET, d, force=True, contact_model=contact_model)
    made_on = yaml.safe_load(listing.read_text()).get("contact_model", DEFAULT_CONTACT_MODEL)
    if made_on != contact_model:
        raise SystemExit(f"{listing}: its demos were made on {made_on!r}, not {contact_model!r}")
    return d / task


def run_cell(task: str, variant: str, method: str, augment: bool, attempts: int, seed: int,
             perception: str, images: bool = False, velocity_scale: float | None = None,
             profile: str = "skillgen_ros", keep_indices: bool = False,
             contact_model: str = DEFAULT_CONTACT_MODEL) -> dict:
    """One (task, variant, method, profile) cell in this process; returns counts, CI, timings and the
    initiation candidates used (keep_indices: which attempt indices succeeded, too).
    velocity_scale None: SimEnvConfig's default (graphs.yaml's planner)."""
    from skillgen_ros.core.dataset.paper import paper_rate
    from skillgen_ros.core.dataset.report import wilson_interval
    from skillgen_ros.core.generation.session import RunRequest, run_generation
    from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv
    from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos
    from skillgen_ros.core.tasks import get_task

    if velocity_scale is None:
        velocity_scale = SimEnvConfig.velocity_scale
    task_spec = get_task(task)
    demo_dir = source_demo_dir(task, contact_model)
    source = source_digest.record(demo_dir)  # the demos as loaded, before the cell runs
    demos = load_source_demos(expand_bag_paths([str(demo_dir)]), task_spec)
    env = SimGenerationEnv(SimEnvConfig(perception=perception, seed=seed, images=images, velocity_scale=velocity_scale,
                                        contact_model=contact_model))
    with tempfile.TemporaryDirectory() as out:
        req = RunRequest(task=task, variant=variant, method=method, attempts=attempts, seed=seed, augment=augment,
                         output_dir=os.path.join(out, "run"), video_attempts=0, profile=profile)
        cpu0, t0 = time.process_time(), time.perf_counter()
        run = run_generation(env, demos, task_spec, req, write_report=False)
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - t0
    env.close()
    lo, hi = wilson_interval(run.successes, run.attempts)
    used = Counter(str(n) for r in run.results for n in r.initiation_candidates_used)
    return {"task": task, "variant": variant, "method": method, "augment": augment, "profile": profile,
            "initiation_candidates": req.config().initiation_candidates,
            "initiation_candidates_used": dict(sorted(used.items(), key=lambda kv: int(kv[0]))),
            "attempts_with_retry": sum(any(n > 1 for n in r.initiation_candidates_used) for r in run.results),
            "perception": perception, "contact_model": contact_model, "source_demos": source,
            "images": images, "velocity_scale": velocity_scale, "attempts": run.attempts, "successes": run.successes,
            "rate": run.successes / run.attempts, "wilson95": [lo, hi],
            "paper_rate": paper_rate(task, variant, method, augment),
            "failures": {k: v for k, v in run.failures.items() if v},
            "cpu_seconds": cpu, "wall_seconds": wall, "seconds_per_attempt": wall / run.attempts,
            "successes_per_hour_per_core": run.successes / cpu * 3600 if cpu > 0 else 0.0,
            **({"successful_indices": sorted(r.index for r in run.results if r.success)} if keep_indices else {})}


def _attempt_records(out_dir: str) -> list[dict]:
    """Every attempt's recorded attrs (success, reason, timings, ...) from a run's demo/failed files."""
    import h5py

    recs = []
    for name in ("demo.hdf5", "failed.hdf5"):
        path = os.path.join(out_dir, name)
        if not os.path.exists(path):
            continue
        with h5py.File(path, "r") as f:
            for d in f["data"].values():
                recs.append({k: (json.loads(v) if k == "timings" else v) for k, v in d.attrs.items()
                             if k in ("success", "reason", "timings", "index")})
    return recs


def _graph_run(attempts: int, seed: int, task: str = "Square", variant: str = "D0") -> dict:
    """`skillgen generate` through the datagen graph (estimated poses, the README's main job);
    time per attempt and the outcomes from the attempts' own records."""
    import subprocess

    from skillgen_ros import rosenv

    env = rosenv.ros_environment(dict(os.environ))
    env.setdefault("ROS_DOMAIN_ID", "77")
    with tempfile.TemporaryDirectory() as out:
        g = os.path.join(out, "g")
        cmd = [str(ROOT / ".venv" / "bin" / "skillgen"), "generate", "--task", task, "--variant", variant,
               "--attempts", str(attempts), "--seed", str(seed), "--output", g, "--no-bag",
               "--video-attempts", "0"]  # as the in-process cell: no MP4
        t0 = time.perf_counter()
        p = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=ROOT, timeout=3600)
        wall = time.perf_counter() - t0
        recs = _attempt_records(g)
    secs = [r["timings"]["total"] for r in recs if "timings" in r]
    ok = p.returncode == 0 and len(recs) == attempts
    fails = Counter(str(r["reason"]) for r in recs if not r["success"])
    return {"ok": ok, "seconds_per_attempt": sum(secs) / len(secs) if secs else None, "wall_with_startup_s": wall,
            "attempts": len(recs), "successes": sum(bool(r["success"]) for r in recs), "failures": dict(fails),
            "successful_indices": sorted(int(r["index"]) for r in recs if r["success"]),
            "exit": p.returncode, "tail": (p.stdout[-600:] + p.stderr[-600:]) if not ok else p.stdout[-300:]}


def graph_rates(attempts: int, seed: int, tasks=None) -> dict:
    """Every task's D0 (or `tasks`') through the ROS graph (estimated poses, the default profile) beside the
    same attempts in-process with estimated poses: the same (seed, index) should succeed on both paths."""
    from skillgen_ros.core.tasks import TASK_NAMES

    out = {"attempts": attempts, "seed": seed, "perception": "estimate", "variant": "D0", "tasks": {}}
    for task in tasks or TASK_NAMES:
        g = _graph_run(attempts, seed, task, "D0")
        inproc = run_cell(task, "D0", "skillgen", False, attempts, seed, "estimate", keep_indices=True)
        out["tasks"][task] = {"graph": g, "in_process": inproc,
                              "same_outcomes": g["successful_indices"] == inproc.get("successful_indices")}
        print(task, g["successes"], "/", g["attempts"], "graph;", inproc["successes"], "/", attempts, "in-process",
              flush=True)
    return out


def graph_overhead(attempts: int, seed: int, repeats: int = 3) -> dict:
    """The same attempts (Square D0 skillgen, estimated poses) through the ROS graph and in-process,
    `repeats` back-to-back pairs; the ratio is the median of the pairs' ratios (the VM's speed
    drifts by tens of percent over minutes, so only same-time pairs compare).

    Time per attempt excludes graph start-up: both sides report the attempts' own wall time."""
    pairs = []
    for _ in range(repeats):
        inproc = run_cell("Square", "D0", "skillgen", False, attempts, seed, "estimate")
        graph = _graph_run(attempts, seed)
        ratio = (graph["seconds_per_attempt"] / inproc["seconds_per_attempt"]
                 if graph["ok"] and graph["seconds_per_attempt"] else None)
        pairs.append({"in_process_seconds_per_attempt": inproc["seconds_per_attempt"], "in_process_rate": inproc["rate"],
                      "graph_seconds_per_attempt": graph["seconds_per_attempt"], "ratio": ratio,
                      "graph_wall_with_startup_s": graph["wall_with_startup_s"], "graph_exit": graph["exit"],
                      "graph_tail": graph["tail"]})
    ratios = sorted(p["ratio"] for p in pairs if p["ratio"] is not None)
    med = ratios[len(ratios) // 2] if ratios else None
    return {"attempts": attempts, "repeats": repeats, "perception": "estimate",
            "ratio_graph_to_in_process": med, "ratios": ratios, "pairs": pairs,
            "in_process_seconds_per_attempt": sorted(p["in_process_seconds_per_attempt"] for p in pairs)[len(pairs) // 2],
            "graph_seconds_per_attempt": sorted(p["graph_seconds_per_attempt"] or float("inf") for p in pairs)[len(pairs) // 2]}


EXTRAS = {  # name -> (attempts, seed, perception) -> result; re-measured alone with --only NAME
    "throughput_lowdim": lambda n, seed, perc: run_cell("Square", "D0", "skillgen", False, n, seed + 1, perc),
    "throughput_images": lambda n, seed, perc: run_cell("Square", "D0", "skillgen", False, max(3, n // 4), seed + 1,
                                                        perc, images=True),
    "perception_estimate": lambda n, seed, perc: run_cell("Square", "D1", "skillgen", False, n, seed + 2, "estimate"),
    "perception_ground_truth": lambda n, seed, perc: run_cell("Square", "D1", "skillgen", False, n, seed + 2,
                                                              "ground_truth"),
    "graph_overhead": lambda n, seed, perc: graph_overhead(max(3, n // 4), seed + 3),
    "graph_rates": lambda n, seed, perc: graph_rates(max(3, n // 10), seed + 4),
}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--attempts", type=int, default=200)
    ap.add_argument("--quick", action="store_true", help="10 attempts per cell, no D1 cells")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--perception", default="ground_truth", choices=["ground_truth", "estimate"])
    ap.add_argument("--tasks", nargs="*", default=list(TASKS))
    ap.add_argument("--variants", nargs="*", default=[], help="only these variants (default: all of each task)")
    ap.add_argument("--profiles", nargs="+", default=list(PROFILES), choices=PROFILES)
    ap.add_argument("--methods", nargs="+", default=[], choices=[_key(m, aug) for m, aug in METHODS] + ["replay_noise"],
                    help="only these methods' cells")
    ap.add_argument("--force", action="store_true", help="rerun cells the JSON already has")
    ap.add_argument("--skip-graph", action="store_true")
    ap.add_argument("--skip-extras", action="store_true", help="cells only (no throughput / perception / graph parts)")
    ap.add_argument("--velocity-scale", type=float, default=None,
                    help="planned motions' fraction of the Panda's V/A/J limits in the cells (A/B of the timing; "
                         "default and the extras: SimEnvConfig's, as graphs.yaml's planner)")
    ap.add_argument("--contact-model", default=DEFAULT_CONTACT_MODEL, choices=sorted(CONTACT_MODELS),
                    help="the sim's contact model for the cells (core/sim/contact_model.py); another than the default "
                         "needs its own --out and --skip-extras, and makes its source demos in out/demos/<model>/")
    ap.add_argument("--out", default=str(DEFAULT_OUT))
    ap.add_argument("--only", nargs="+", default=[], choices=sorted(EXTRAS), metavar="PART",
                    help=f"only (re)measure these of {sorted(EXTRAS)} and update the JSON in place")
    a = ap.parse_args(argv)
    n = 10 if a.quick else a.attempts
    path = Path(a.out)
    out = _load(path)
    held = out.get("contact_model", DEFAULT_CONTACT_MODEL if out["cells"] else a.contact_model)
    if held != a.contact_model or \
            a.contact_model != DEFAULT_CONTACT_MODEL and (path == DEFAULT_OUT or a.only or not a.skip_extras):
        raise SystemExit(f"the {a.contact_model} contact model's cells go to their own JSON, cells only (--out, "
                         f"--skip-extras); {path} holds the {held} model's")
    out["contact_model"] = a.contact_model
    rerun = " ".join(["python", "bench/datagen/run.py", *(sys.argv[1:] if argv is None else argv)])
    if a.only:
        for part in a.only:
            if part == "graph_rates" and set(a.tasks) != set(TASKS):  # these tasks again, the others kept
                new = graph_rates(max(3, n // 10), a.seed + 4, a.tasks)
                for t in new["tasks"].values():
                    t.update(rerun=rerun, measured=time.strftime("%Y-%m-%d"))
                out[part] = {**out.get(part, {}), "tasks": {**out.get(part, {}).get("tasks", {}), **new["tasks"]}}
                continue
            out[part] = EXTRAS[part](n, a.seed, a.perception)
            out[part]["rerun"] = rerun
            print(part, json.dumps({k: v for k, v in out[part].items() if k != "pairs"}, indent=2))
        _save(path, out)
        return 0
    jobs = _jobs(a, n)
    for task in sorted({j[0] for j in jobs}):  # a model's demos are made before any worker needs them
        source_demo_dir(task, a.contact_model)
    done = _done(out, n, a.seed)
    todo = [j for j in jobs if a.force or _job_key(j) not in done]
    print(f"{len(jobs)} cells, {len(jobs) - len(todo)} already in {path}, running {len(todo)}", flush=True)
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=a.workers) as pool:
        futures = {pool.submit(_star, j): j for j in todo}
        for fut in as_completed(futures):
            cell = fut.result()
            cell.update(seed=a.seed, rerun=rerun, measured=time.strftime("%Y-%m-%d"))
            out["cells"] = [c for c in out["cells"] if cell_key(c) != cell_key(cell)] + [cell]
            out["summary"] = summarize(out["cells"])
            _save(path, out)  # resumable: every finished cell is on disk
            print(f"{cell['task']} {cell['variant']} {_key(cell['method'], cell['augment'])} [{cell['profile']}]: "
                  f"{cell['successes']}/{cell['attempts']} ({cell['wall_seconds']:.0f} s)", flush=True)
    out.update(benchmark="datagen", machine=machine_info(), attempts_per_cell=n, seed=a.seed,
               perception=a.perception, cells_wall_seconds=time.perf_counter() - t0, rerun=rerun)
    if not a.skip_extras:
        for k, f in EXTRAS.items():
            if not (k in ("graph_overhead", "graph_rates") and a.skip_graph) and (a.force or k not in out):
                out[k] = f(n, a.seed, a.perception)
                _save(path, out)
    out["summary"] = summarize(out["cells"])
    _save(path, out)
    print(json.dumps(out["summary"], indent=2))
    print(f"wrote {path}")
    return 0


def _jobs(a, n: int) -> list[tuple]:
    """(task, variant, method, augment, attempts, seed, perception, images, velocity_scale, profile,
    contact_model) per cell: profile-free methods once (under `paper`), the others under each profile asked for."""
    jobs = []
    for task in a.tasks:
        for variant in task_variants(task):
            if (a.quick and variant == "D1") or (a.variants and variant not in a.variants):
                continue
            for method, aug in METHODS:
                profiles = [p for p in a.profiles if method not in PROFILE_FREE] or \
                    (["paper"] if method in PROFILE_FREE else [])
                for prof in profiles:
                    jobs.append((task, variant, method, aug, n, a.seed, a.perception, False, a.velocity_scale, prof,
                                 a.contact_model))
        if not a.variants or "D0" in a.variants:
            jobs.append((task, "D0", "replay_noise", False, n, a.seed, a.perception, False, a.velocity_scale, "paper",
                         a.contact_model))
    if a.methods:
        jobs = [j for j in jobs if _key(j[2], j[3]) in a.methods]
    return jobs


def _done(out: dict, attempts: int, seed: int) -> set[tuple]:
    """The cells a run skips: measured with these attempts and seed, from the source demos there today (a cell
    whose demos were remade since runs again; one from before digests were recorded counts as done)."""
    return {cell_key(c) for c in out["cells"] if c.get("attempts") == attempts
            and c.get("seed", out.get("seed")) == seed and not source_digest.is_stale(c)}


def _job_key(j: tuple) -> tuple:
    return j[0], j[1], _key(j[2], j[3]), j[9]


def _key(method: str, augment: bool) -> str:
    return method + ("+IA" if augment else "")


def _load(path: Path) -> dict:
    """The JSON so far; cells measured before profiles existed (no "profile") are dropped: they ran
    another MimicGen baseline and cannot be resumed into a profiled table."""
    out = json.loads(path.read_text()) if path.exists() else {}
    out.setdefault("benchmark", "datagen")
    out["cells"] = [c for c in out.get("cells", []) if "profile" in c]
    return out


def _save(path: Path, out: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(out, indent=2))
    os.replace(tmp, path)


def _star(args):
    return run_cell(*args[:9], profile=args[9], contact_model=args[10])


if __name__ == "__main__":
    sys.exit(main())

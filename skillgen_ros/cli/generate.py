"""`skillgen generate`: the main job. Starts the generation graph, triggers a run, shows progress.

    skillgen generate                       Square D1, skillgen, 50 attempts through the full graph
    skillgen generate --task Square --variant D2 --method mimicgen --attempts 200 --seed 3
    skillgen generate --profile paper       the paper's Algorithm 1 (see core/generation/profile.py)
    skillgen generate --in-process          same algorithm, no ROS graph (SimGenerationEnv)
    skillgen generate --workers 4           the same run on 4 Ray workers (docs/distributed.md)

First, before any node starts, `preflight` checks what can be checked here: task, variant,
method, selection, profile, output dir, and that the source demos load with valid annotations;
a mistake is one line "REASON: message" and exit 2 within a second or two. Graph mode then
launches the `datagen` graph (sim_driver in lockstep, perception in estimate mode, planner,
skill_replay, datagen, recorder) as separate processes, each logging to <output>/logs/<node>.log
(only their warnings and errors reach the terminal; `--verbose` streams everything), sends a
Generate goal through SkillGenClient, draws a progress bar from the feedback, prints the success
rate and where the dataset, bag, report and logs are, and stops the graph. Ctrl-C cancels the run
cleanly.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

from skillgen_ros.core.errors import SkillGenError
from skillgen_ros.core.generation.selection import strategy_help
from skillgen_ros.core.validation import USE_DEFAULT


def _parser() -> argparse.ArgumentParser:
    from skillgen_ros.core.tasks import TASK_NAMES  # the registry's names, so the help cannot drift

    p = argparse.ArgumentParser(prog="skillgen generate", description=__doc__.split("\n\n")[0])
    p.add_argument("--task", default="Square", help=f"one of {', '.join(TASK_NAMES)} (default Square)")
    p.add_argument("--variant", default="D1",
                   help="reset distribution: D0, D1, D2 or a clutter variant (docs/tasks.md)")
    p.add_argument("--method", default="skillgen", help="skillgen, mimicgen or replay_noise")
    p.add_argument("--attempts", type=int, default=50, help="generation attempts (default 50)")
    p.add_argument("--target-successes", type=int, default=0,
                   help="stop once this many succeeded (0 = run every attempt; --attempts is then a cap)")
    p.add_argument("--seed", type=int, default=0, help="run seed: attempt i depends only on (seed, i)")
    p.add_argument("--first-index", type=int, default=0,
                   help="index of the first attempt (shards of one run: disjoint ranges, one seed)")
    p.add_argument("--augment", action="store_true", help="initiation augmentation (t=0.08 m, r=80 deg)")
    p.add_argument("--selection", default="random",
                   help=f"skillgen: {strategy_help()}; random is the paper's; mimicgen uses its task config's "
                        "(mimicgen.py)")
    p.add_argument("--source-demos", default="", help="directory of source bags (default bags/<task>)")
    p.add_argument("--output", default="", help="output directory (default out/<task>_<variant>_<method>_seed<seed>)")
    p.add_argument("--no-bag", action="store_true", help="do not record the session to MCAP")
    p.add_argument("--record", default="", metavar="FIRST:COUNT",
                   help="record only attempts FIRST..FIRST+COUNT-1 of the run (default: all)")
    p.add_argument("--video-attempts", type=int, default=-1, metavar="N",
                   help="attempts filmed into the run's MP4 (default 4; 0 = no video)")
    p.add_argument("--profile", default="", choices=["", "paper", "skillgen_ros"],
                   help="algorithm profile: paper (the paper's Algorithm 1) or skillgen_ros (default: "
                        "initiation candidates, release moves, planner start repairs, collision filter)")
    p.add_argument("--initiation-candidates", type=int, default=0, metavar="N",
                   help="skillgen: initiation poses tried per skill when one is unreachable (0 = the profile's: "
                        "skillgen_ros 6, paper 1)")
    p.add_argument("--in-process", action="store_true", help="run without the ROS graph")
    p.add_argument("--perception", default="estimate", choices=["estimate", "ground_truth"],
                   help="in-process only; the graph uses params/perception.yaml")
    p.add_argument("--observation-source", default="ground_truth", choices=["ground_truth", "estimate"],
                   help="what obs/<id>_pose records: the sim's true poses, or the estimates (in-process; the "
                        "graph uses params/datagen.yaml's observation_source)")
    p.add_argument("--startup-timeout", type=float, default=60.0,
                   help="seconds to wait for the graph's datagen node to answer")
    p.add_argument("--verbose", action="store_true",
                   help="stream every node's output here (default: <output>/logs/<node>.log; only warnings, "
                        "errors, the progress bar and the summary here); with --workers, each worker's status")
    d = p.add_argument_group("distributed (docs/distributed.md)")
    d.add_argument("--workers", type=int, default=1, metavar="N",
                   help="run the attempts on N Ray workers (in-process envs with --in-process, else one node "
                        "graph per worker in its own ROS_DOMAIN_ID); 1 = this process")
    d.add_argument("--address", default="", metavar="ADDR",
                   help="join a Ray cluster: auto, host:port or ray://host:port (default: a local instance)")
    d.add_argument("--resume", action="store_true",
                   help="continue the interrupted distributed run in --output; finished indices are not re-run")
    d.add_argument("--dashboard", action="store_true", help="start Ray's dashboard (127.0.0.1:8265)")
    d.add_argument("--domain-ids", default="", metavar="A-B",
                   help="graph workers lease their ROS_DOMAIN_IDs from these (default 1-101)")
    return p


def _output(a) -> str:
    """--output, else a fresh out/<task>_<variant>_<method>_seed<seed>_<time> (runs never overwrite)."""
    if a.output:
        return a.output
    if not hasattr(a, "_auto_output"):
        stamp = time.strftime("%Y%m%d-%H%M%S")
        a._auto_output = os.path.join("out", f"{a.task}_{a.variant}_{a.method}{'_ia' if a.augment else ''}"
                                             f"_seed{a.seed}_{stamp}")
    return a._auto_output


def _window(spec: str) -> tuple[int, int]:
    if not spec:
        return 0, 0
    try:
        first, count = (int(x) for x in spec.split(":"))
    except ValueError:
        raise SkillGenError(f"--record wants FIRST:COUNT, got {spec!r}", reason="INVALID_ARGUMENT") from None
    if first < 0 or count <= 0:
        raise SkillGenError(f"--record wants FIRST >= 0 and COUNT > 0, got {spec!r}", reason="INVALID_ARGUMENT")
    return first, count


def _print_result(attempts, successes, failures: dict, paths: dict) -> None:
    rate = successes / attempts if attempts else 0.0
    print(f"\nsuccess rate: {successes}/{attempts} = {100 * rate:.1f}%")
    if failures:
        print("failures: " + ", ".join(f"{k} {v}" for k, v in sorted(failures.items())))
    for k, v in paths.items():
        if v:
            print(f"{k:8s} {v}")


def _html_next_to(report_md: str) -> str:
    """report.html, written beside report.md (core/dataset/report_html.py), if the run wrote one."""
    from skillgen_ros.core.dataset.report_html import REPORT_HTML

    path = os.path.join(os.path.dirname(report_md), REPORT_HTML) if report_md else ""
    return path if path and os.path.exists(path) else ""


def _request(a):
    """The command line as a RunRequest (in-process and distributed runs)."""
    from skillgen_ros.core.generation.session import RunRequest

    return RunRequest(task=a.task, variant=a.variant, method=a.method, attempts=a.attempts,
                      target_successes=a.target_successes, seed=a.seed, first_index=a.first_index,
                      augment=a.augment, selection=a.selection, output_dir=_output(a), source_demos=a.source_demos,
                      observation_source=a.observation_source,
                      **({"video_attempts": a.video_attempts} if a.video_attempts >= 0 else {}),
                      **({"initiation_candidates": a.initiation_candidates} if a.initiation_candidates else {}),
                      **({"profile": a.profile} if a.profile else {}))


def preflight(a):
    """Check, before any node starts, everything the graph would reject later: the request (task,
    method, selection, profile, counts, output dir), the variant, and the source demos with their
    annotations (loaded exactly as datagen loads them). Returns (RunRequest, source demos)."""
    from skillgen_ros.core.generation.session import validate_request
    from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos
    from skillgen_ros.core.tasks import TASK_NAMES, get_task

    req = _request(a)
    get_task(req.task).objects_for(req.variant)  # UNKNOWN_TASK / UNKNOWN_VARIANT, naming the known ones
    demos_dir = a.source_demos or os.path.join("bags", a.task)
    paths = expand_bag_paths([demos_dir])
    if not paths:
        raise SkillGenError(f"no source demo bags under {demos_dir}", reason="NO_SOURCE_DEMOS")
    demos = load_source_demos(paths, get_task(a.task))
    validate_request(req, TASK_NAMES)  # last: it creates the output dir
    return req, demos


def run_in_process(a) -> int:
    from tqdm import tqdm

    from skillgen_ros.core.generation.session import run_generation
    from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv
    from skillgen_ros.core.tasks import get_task

    req, demos = preflight(a)
    env = SimGenerationEnv(SimEnvConfig(perception=a.perception, seed=a.seed))
    bar = tqdm(total=a.attempts, unit="attempt", dynamic_ncols=True)

    def progress(p):
        bar.update(p.attempts - bar.n)
        bar.set_postfix(success=f"{p.successes}/{p.attempts}", rate=f"{100 * p.rate:.0f}%")

    try:
        run = run_generation(env, demos, get_task(a.task), req, on_progress=progress)
    finally:
        bar.close()
        env.close()
    _print_result(run.attempts, run.successes, {k: v for k, v in run.failures.items() if v},
                  {"dataset": run.dataset_path, "failed": run.failed_path, "report": run.report_path,
                   "html": run.html_path, "video": run.video_path})
    return 0


def run_graph(a) -> int:
    from tqdm import tqdm

    from skillgen_ros.cli.launcher import graph_client
    from skillgen_ros.client import SkillGenClient

    preflight(a)  # before any node starts
    logs = None if a.verbose else os.path.join(_output(a), "logs")
    # datagen and the recorder write only under their roots; an explicit --output is the user's choice
    roots = ["--ros-args", "-p", f"writable_roots:=['{os.path.abspath(a.output)}']"] if a.output else []
    with graph_client("datagen", SkillGenClient, "datagen 'generate'", a.startup_timeout,
                      ros_args=roots, log_dir=logs) as (graph, client):
        ok = client.generate(task=a.task, variant=a.variant, method=a.method, attempts=a.attempts,
                             target_successes=a.target_successes, seed=a.seed, first_index=a.first_index,
                             augment=a.augment, augment_translation=USE_DEFAULT, augment_rotation_deg=USE_DEFAULT,
                             selection=a.selection, source_demos=a.source_demos, output_dir=_output(a),
                             record_bag=not a.no_bag, record_first=_window(a.record)[0],
                             record_count=_window(a.record)[1], video_attempts=a.video_attempts,
                             initiation_candidates=a.initiation_candidates, profile=a.profile)
        if not ok:
            raise SkillGenError("datagen rejected the goal (busy)", reason="REJECTED")
        bar, shown = None, None  # drawn from the first feedback: a goal that fails at once prints only its error
        try:
            while not client.is_done():
                fb = client.feedback()
                if fb is not None and (fb.attempts, fb.successes) != shown:  # redrawn when an attempt ends
                    shown = (fb.attempts, fb.successes)
                    if bar is None:  # its rate counts from here, not from a zero at the first feedback
                        bar = tqdm(total=a.attempts, initial=fb.attempts, unit="attempt", dynamic_ncols=True)
                    bar.update(fb.attempts - bar.n)
                    bar.set_postfix(success=f"{fb.successes}/{fb.attempts}", rate=f"{100 * fb.success_rate:.0f}%",
                                    eta=f"{fb.eta_seconds:.0f}s")
                if graph.poll() is not None:
                    raise SkillGenError(f"the graph stopped (exit {graph.returncode})"
                                        + (f"; node logs in {logs}" if logs else ""), reason="GRAPH_DIED")
                time.sleep(0.2)
        except KeyboardInterrupt:
            client.cancel()
            print("\ncanceling ...", file=sys.stderr)
        finally:
            if bar is not None:
                bar.close()
        res = client.result(timeout=120)
        if not res.accepted:
            raise SkillGenError(res.message, reason=res.reason)
        _print_result(res.attempts, res.successes, {f.reason: f.count for f in res.failures},
                      {"dataset": res.dataset_path, "failed": res.failed_path, "report": res.report_path,
                       "html": _html_next_to(res.report_path), "bag": res.bag_path, "logs": logs})
        if res.reason not in ("OK", "CANCELED"):
            print(f"run ended early: {res.reason}: {res.message}", file=sys.stderr)
            return 1
        return 0


def main(argv: list[str]) -> int:
    a = _parser().parse_args(argv)
    try:
        if a.workers > 1 or a.address or a.resume:
            from skillgen_ros.cli.distributed import run_distributed_cli

            return run_distributed_cli(a, _request(a))
        return run_in_process(a) if a.in_process else run_graph(a)
    except SkillGenError as e:
        print(str(e), file=sys.stderr)
        return 2

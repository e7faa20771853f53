"""`skillgen deploy`: evaluate a Hybrid Skill Policy checkpoint with N rollouts on held-out reset seeds.

    skillgen deploy --checkpoint out/policy/best.pt --task Square --variant D1 --rollouts 50 --seed 0
    skillgen deploy ... --mode reg            HSP-Reg initiation (class: HSP-Class, tamp: HSP-TAMP, bc: baseline)
    skillgen deploy ... --in-process          the same rollouts without ROS (core/deploy.evaluate)

Graph mode launches the `deploy` graph (sim_driver in lockstep, perception, planner, hsp,
recorder), and for each rollout i sends a RunTask goal that resets the scene with the held-out
seed rollout_seed(seed, i) (core/deploy/seeds.py: bit 31 set, so it never equals a generation
scene seed) while the recorder writes OUTPUT/rollout_<i>/ (MCAP; Foxglove opens it). It prints the
success rate with its 95% Wilson interval and the failure breakdown, and writes OUTPUT/results.json.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import threading
import time

import numpy as np

from skillgen_ros.core.errors import SkillGenError


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="skillgen deploy", description=__doc__.split("\n\n")[0])
    p.add_argument("--checkpoint", required=True)
    p.add_argument("--task", required=True)
    p.add_argument("--variant", default="D0")
    p.add_argument("--rollouts", type=int, default=50)
    p.add_argument("--seed", type=int, default=0, help="evaluation seed: rollout i resets with rollout_seed(seed, i)")
    p.add_argument("--first-rollout", type=int, default=0)
    p.add_argument("--mode", default="class", help="initiation: class, reg, tamp (privileged) or bc (MimicGen baseline)")
    p.add_argument("--max-steps", type=int, default=0, help="control steps per rollout (0: params/hsp.yaml's)")
    p.add_argument("--output", default="", help="directory for results.json and the bags (default out/deploy_...)")
    p.add_argument("--no-bag", action="store_true", help="graph mode: do not record the rollouts")
    p.add_argument("--in-process", action="store_true", help="run without the ROS graph")
    p.add_argument("--workers", type=int, default=1,
                   help="in-process: spread the rollouts over N Ray workers (docs/distributed.md)")
    p.add_argument("--address", default="", help="with --workers: join this Ray cluster (auto, host:port, ray://...)")
    p.add_argument("--device", default="cpu", help="in-process: torch device")
    p.add_argument("--perception", default="ground_truth", choices=["ground_truth", "estimate"],
                   help="in-process only; the graph uses its perception node's mode")
    p.add_argument("--startup-timeout", type=float, default=120.0)
    return p


def _output(a) -> str:
    return a.output or os.path.join("out", f"deploy_{a.task}_{a.variant}_{a.mode}_seed{a.seed}_"
                                           f"{time.strftime('%Y%m%d-%H%M%S')}")


def _report(summary, out: str, extra: dict) -> None:
    print(f"\n{summary.line()}")
    if summary.failures:
        print("failures: " + ", ".join(f"{k} {v}" for k, v in summary.failures.items()))
    print(f"mean steps {summary.mean_steps:.0f}, pi+T {summary.inference_ms_per_step:.2f} ms per policy step")
    os.makedirs(out, exist_ok=True)
    path = os.path.join(out, "results.json")
    with open(path, "x") as f:  # created, never overwritten (main checks before any rollout)
        json.dump({**summary.to_json(), **extra, "command": "skillgen deploy " + " ".join(sys.argv[2:])}, f, indent=2)
    print(f"results  {path}")


class HspClient:
    """RunTask goals and the recorder's services from one private context (as SkillGenClient)."""

    def __init__(self, domain_id: int | None = None):
        from skillgen_ros import rosenv  # noqa: F401

        import rclpy
        from skillgen_ros.action_client import SafeActionClient as ActionClient
        from rclpy.executors import SingleThreadedExecutor

        from skillgen_interfaces.action import RunTask
        from skillgen_interfaces.srv import Recorder

        self.RunTask, self.Recorder = RunTask, Recorder
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node("hsp_client", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.action = ActionClient(self.node, RunTask, "run_task")
        self.rec = {k: self.node.create_client(Recorder, f"recorder/{k}") for k in ("start", "stop")}
        self.feedback: list = []
        self._stop = threading.Event()
        self._spin = threading.Thread(target=self._loop, daemon=True)
        self._spin.start()

    def _loop(self):
        while not self._stop.is_set() and self.context.ok():
            self.executor.spin_once(timeout_sec=0.05)

    def wait_for_server(self, timeout: float) -> bool:
        """Discovered and answering: a probe goal (empty task, rejected unrun) got its answer."""
        from skillgen_ros.answered import detached, first_answer, sleep_until_done

        end = time.monotonic() + timeout
        if not self.action.wait_for_server(timeout_sec=timeout):
            return False
        return first_answer(lambda: detached(self.action.send_goal_async(self.RunTask.Goal(task=""))),
                            sleep_until_done,
                            max(0.1, end - time.monotonic())) is not None

    def send(self, timeout: float = 30.0, **fields):
        """Send a goal; the goal handle (accepted or not)."""
        self.feedback = []
        fut = self.action.send_goal_async(self.RunTask.Goal(**fields),
                                          feedback_callback=lambda m: self.feedback.append(m.feedback))
        if not _wait(fut, timeout):
            raise SkillGenError("the run_task goal was not answered", reason="TIMEOUT")
        return fut.result()

    def run(self, timeout: float = 600.0, **fields):
        """One goal to its end: the RunTask result (a rejected goal raises REJECTED)."""
        handle = self.send(**fields)
        if not handle.accepted:
            raise SkillGenError("the hsp node rejected the goal (busy?)", reason="REJECTED")
        fut = handle.get_result_async()
        if not _wait(fut, timeout):
            handle.cancel_goal_async()
            raise SkillGenError(f"the rollout did not finish within {timeout:.0f} s", reason="TIMEOUT")
        return fut.result().result

    def recorder(self, what: str, output: str = "", timeout: float = 15.0):
        cli = self.rec[what]
        if not cli.wait_for_service(timeout_sec=5.0):
            return None
        fut = cli.call_async(self.Recorder.Request(output=output))
        return fut.result() if _wait(fut, timeout) else None

    def close(self) -> None:
        self._stop.set()
        self._spin.join(2.0)
        self.node.destroy_node()
        self.context.try_shutdown()


def _wait(fut, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while not fut.done() and time.monotonic() < end:
        time.sleep(0.01)
    return fut.done()


def result_to_rollout(res, reset_seed: int):
    """A RunTask result as the executor's RolloutResult (request-level failures raise instead)."""
    from skillgen_ros.core.deploy import DeployReason, RolloutResult, SkillLog

    try:
        reason = DeployReason(res.reason)
    except ValueError:
        raise SkillGenError(res.message, reason=res.reason) from None
    if reason is DeployReason.BAD_CHECKPOINT and not res.steps:
        raise SkillGenError(res.message, reason=res.reason)
    skills = tuple(SkillLog(**{**s, "initiation": tuple(s["initiation"])}) for s in json.loads(res.skill_log or "[]"))
    ee = np.asarray(res.ee_poses, float).reshape(-1, 7)
    return RolloutResult(success=bool(res.success), reason=reason, message=res.message, steps=int(res.steps),
                         reset_seed=reset_seed, skills=skills, ee_trajectory=ee,
                         policy_seconds=float(res.inference_ms_per_step) * sum(max(0, s.policy_steps) for s in skills) / 1000,
                         policy_steps=sum(max(0, s.policy_steps) for s in skills))


def run_in_process(a) -> int:
    from skillgen_ros.core.deploy import evaluate

    def show(i, r):
        print(f"rollout {i}: {r.reason.value} after {r.steps} steps ({r.message})", flush=True)

    if a.workers > 1 or a.address:
        from skillgen_ros.core.distributed.evaluate import evaluate_distributed

        s = evaluate_distributed(a.checkpoint, a.task, a.variant, a.mode, a.rollouts, a.seed, workers=a.workers,
                                 address=a.address, first_index=a.first_rollout, perception=a.perception,
                                 on_range=lambda i, e: [show(i + k, r) for k, r in enumerate(e.results)])
    else:
        s = evaluate(a.checkpoint, a.task, a.variant, a.mode, a.rollouts, a.seed, device=a.device,
                     perception=a.perception, on_rollout=show, first_index=a.first_rollout,
                     **({"config": _config(a)} if a.max_steps else {}))
    _report(s, _output(a), {"path": "in-process"})
    return 0


def _config(a):
    from skillgen_ros.core.deploy import DeployConfig

    return DeployConfig(mode=a.mode, max_steps=a.max_steps)


def rollouts_through_graph(client: HspClient, a, out: str) -> list:
    from skillgen_ros.core.deploy import rollout_seed

    results = []
    for i in range(a.first_rollout, a.first_rollout + a.rollouts):
        seed = rollout_seed(a.seed, i)
        bag = "" if a.no_bag else os.path.join(os.path.abspath(out), f"rollout_{i:03d}")
        if bag and (client.recorder("start", bag) is None):
            print("recorder not available: rollouts are not recorded", file=sys.stderr)
            bag = ""
        try:
            res = client.run(task=a.task, checkpoint=os.path.abspath(a.checkpoint), initiation_mode=a.mode,
                             max_steps=a.max_steps, variant=a.variant, seed=seed)
        finally:
            if bag:
                client.recorder("stop")
        r = result_to_rollout(res, seed)
        print(f"rollout {i}: {r.reason.value} after {r.steps} steps ({r.message}){'  bag ' + bag if bag else ''}",
              flush=True)
        results.append(r)
    return results


def run_graph(a) -> int:
    from skillgen_ros.cli.launcher import graph_client
    from skillgen_ros.core.deploy import summarize

    out = _output(a)
    os.makedirs(out, exist_ok=True)
    # the recorder writes the rollout bags only under its roots; an explicit --output is the user's choice
    roots = ["--ros-args", "-p", f"writable_roots:=['{os.path.abspath(out)}']"] if a.output else []
    with graph_client("deploy", HspClient, "hsp 'run_task'", a.startup_timeout, ros_args=roots) as (_graph, client):
        results = rollouts_through_graph(client, a, out)
        _report(summarize(a.task, a.variant, a.mode, results), out, {"path": "graph"})
        return 0


def main(argv: list[str]) -> int:
    a = _parser().parse_args(argv)
    if a.rollouts < 1 or a.seed < 0 or a.first_rollout < 0:
        print("INVALID_ARGUMENT: --rollouts must be >= 1, --seed and --first-rollout >= 0", file=sys.stderr)
        return 2
    a.output = _output(a)  # fixed once: the timestamped default must name one directory throughout
    if os.path.exists(os.path.join(a.output, "results.json")):
        print(f"OUTPUT_EXISTS: {os.path.join(_output(a), 'results.json')} already exists; choose another --output "
              "(results are never overwritten)", file=sys.stderr)
        return 2
    try:
        return run_in_process(a) if a.in_process else run_graph(a)
    except SkillGenError as e:
        print(str(e), file=sys.stderr)
        return 2

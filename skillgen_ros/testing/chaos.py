"""Chaos checks (issue 19): kill -9 one process of a `skillgen launch <graph> --respawn` graph
while a `generate` run goes on, then check what survived. Shared by test/test_chaos.py and
bench/chaos/run.py, so the test and the benchmark judge a kill the same way.

What a kill must not lose (docs/testing.md, "Chaos"):
- every attempt that finished is in demo.hdf5 (successes) or failed.hdf5 (with its reason), its
  index once, the indices contiguous from the run's first (`read_run`);
- demo.hdf5 validates and holds exactly the run's successes;
- the session bag opens in rosbags' AnyReader, after `recover_bag` if the recorder was killed
  before it finalized the file (`bag_messages`).
"""
from __future__ import annotations

import os
import signal
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import h5py

# Shorter per-call budgets than params/datagen.yaml's (a dead planner costs timeout_plan + timeout_execute),
# still far above what a call takes on a loaded machine: `--ros-args` for the datagen graph.
FAST_TIMEOUTS = ["-p", "datagen:timeout_execute:=30.0", "-p", "datagen:timeout_skill:=60.0",
                 "-p", "datagen:timeout_reset:=20.0"]

# The processes of graphs.yaml's datagen graph, by executable (the container runs sim_driver and
# skill_replay), and the reasons an attempt that needed the killed one fails with: graph_env turns
# a call nobody answers into its stage's reason; the recorder and datagen are in no attempt's path.
# An attempt may also come through: a call that is safe to repeat (estimate_poses, reset_scene) is
# resent every 5 s, and the respawned node answers it.
VICTIMS = ("perception", "planner", "container", "recorder", "datagen")
IN_FLIGHT_REASONS = {
    "perception": {"PERCEPTION_FAILED"},
    "planner": {"PLAN_FAILED", "TIMEOUT"},
    "container": {"TIMEOUT", "SKILL_FAILED", "PLAN_FAILED", "EXECUTION_COLLISION", "PERCEPTION_FAILED"},
    "recorder": set(),
    "datagen": set(),
}


def node_process(launcher_pid: int, exe: str):
    """The live child of the launcher running `exe` (psutil.Process), or None."""
    import psutil

    for k in psutil.Process(launcher_pid).children():
        try:
            if k.status() != psutil.STATUS_ZOMBIE and any(a.endswith(f"/skillgen_ros/{exe}") for a in k.cmdline()):
                return k
        except psutil.Error:  # gone, or not yet reaped
            continue
    return None


def kill(launcher_pid: int, exe: str) -> int:
    """SIGKILL the process running `exe`; returns its pid (the launcher reaps it and respawns)."""
    p = node_process(launcher_pid, exe)
    if p is None:
        raise LookupError(f"no running {exe} under launcher {launcher_pid}")
    os.kill(p.pid, signal.SIGKILL)
    return p.pid


def respawned(launcher_pid: int, exe: str, old_pid: int) -> bool:
    p = node_process(launcher_pid, exe)
    return p is not None and p.pid != old_pid


@dataclass(frozen=True)
class RunFiles:
    """What a run's two HDF5 files hold: each finished attempt's index -> its reason ("OK" = a demo)."""

    reasons: dict[int, str]
    demos: int

    @property
    def attempts(self) -> int:
        return len(self.reasons)

    def after(self, index: int) -> dict[int, str]:
        return {i: r for i, r in self.reasons.items() if i >= index}


def read_run(out_dir: str | os.PathLike, first_index: int = 0) -> RunFiles:
    """Validate demo.hdf5 (robomimic layout) and read both files; raises AssertionError naming the
    problem if an attempt is missing, twice, or a success is not a valid demo."""
    from skillgen_ros.core.dataset.hdf5 import validate_dataset

    out = Path(out_dir)
    summary = validate_dataset(str(out / "demo.hdf5"))
    reasons: dict[int, str] = {}
    for name in ("demo.hdf5", "failed.hdf5"):
        with h5py.File(out / name, "r", locking=False) as f:
            for d in f["data"].values():
                i, why = int(d.attrs["index"]), str(d.attrs["reason"])
                assert i not in reasons, f"attempt {i} is in the files twice"
                assert (why == "OK") == (name == "demo.hdf5"), f"attempt {i} ({why}) is in {name}"
                reasons[i] = why
    assert sorted(reasons) == list(range(first_index, first_index + len(reasons))), \
        f"attempts missing from {out}: have {sorted(reasons)}"
    demos = sum(r == "OK" for r in reasons.values())
    assert summary.num_demos == demos, (summary.num_demos, demos)
    return RunFiles(dict(sorted(reasons.items())), demos)


def bag_messages(bag_dir: str | os.PathLike) -> tuple[int, bool]:
    """(messages rosbags' AnyReader reads, whether the bag had to be recovered first)."""
    from rosbags.highlevel import AnyReader

    from skillgen_ros.core.bag.recover import recover_bag

    recovered = bool(recover_bag(bag_dir))
    with AnyReader([Path(bag_dir)]) as r:
        return sum(1 for _ in r.messages()), recovered


def bag_messages_on_disk(bag_dir: str | os.PathLike) -> int:
    """Messages in the complete chunks of a bag being written (each .mcap scanned up to its last
    complete, CRC-valid chunk): what a SIGKILL of the recorder now must not lose."""
    from skillgen_ros.core.bag.scan import scan_file
    from skillgen_ros.core.errors import BagError

    n = 0
    for f in sorted(Path(bag_dir).glob("*.mcap")):
        try:
            n += sum(scan_file(f).counts.values())
        except (BagError, OSError):  # not even a header yet
            continue
    return n


GOAL = dict(task="Square", variant="D0", method="skillgen", attempts=20, target_successes=3, record_bag=True,
            video_attempts=0)  # 3 successes: at most 2 (attempt 0, the one in flight) can come before the kill


@dataclass
class KillRecord:
    """One kill and what survived it; `problems` empty = survived with nothing lost."""

    victim: str
    in_flight: int = -1  # index of the attempt running when the process died
    reasons: dict = field(default_factory=dict)  # attempt index -> reason, from the files
    successes_after: int = 0  # demos from attempts after the in-flight one
    stage_failures: int = 0  # attempts from the in-flight one on that failed with the killed stage's reason
    bag_messages: int = 0
    bag_on_disk_at_kill: int = 0  # recorder kills: messages in complete chunks when it died
    bag_recovered: bool = False
    respawn_seconds: float = 0.0
    run_reason: str = ""
    problems: list = field(default_factory=list)

    @property
    def survived(self) -> bool:
        return not self.problems


def _wait(pred: Callable[[], bool], timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.1)  # polling observable state (feedback, the launcher's children)
    return bool(pred())


def _check(rec: KillRecord, out: Path, first_index: int) -> RunFiles | None:
    try:
        files = read_run(out, first_index)
    except (AssertionError, OSError, KeyError) as e:  # noqa: PERF203
        rec.problems.append(f"files: {e}")
        return None
    except Exception as e:  # noqa: BLE001 -- DatasetError and the like: the run's files are damaged
        rec.problems.append(f"files: {type(e).__name__}: {e}")
        return None
    rec.reasons = files.reasons
    rec.successes_after = sum(r == "OK" for i, r in files.reasons.items() if i > rec.in_flight)
    return files


def kill_mid_run(launcher_pid: int, make_client: Callable, victim: str, out: Path, seed: int = 0,
                 first_index: int = 0, stop_recording: Callable[[], bool] | None = None,
                 timeout: float = 1800.0) -> KillRecord:
    """Start a generate goal on the graph, kill `victim` once the first attempt is done, wait for the
    launcher to respawn it and the run to end; judge the files. `make_client()` returns a connected
    SkillGenClient (after a datagen kill a new one is made for the respawned server);
    `stop_recording()` stops the recording a killed datagen left running."""
    rec = KillRecord(victim)
    c = make_client()
    try:
        if not c.generate(timeout=120, seed=seed, first_index=first_index, output_dir=str(out), **GOAL):
            rec.problems.append("goal rejected")
            return rec
        if not _wait(lambda: c.is_done() or (c.feedback() is not None and c.feedback().attempts >= 1), timeout) \
                or c.is_done():
            rec.problems.append("the run ended (or hung) before the kill")
            return rec
        if victim == "recorder":  # kill it once a chunk is complete: what it must keep (a kill before the first
            # chunk closes loses the open one by design, max_chunk_age; CI once killed it with none on disk)
            if not _wait(lambda: bag_messages_on_disk(out / "bag") > 0, 300):
                rec.problems.append("the recorder completed no chunk before the kill")
                return rec
            rec.bag_on_disk_at_kill = bag_messages_on_disk(out / "bag")
        rec.in_flight = first_index + c.feedback().attempts
        old, t = kill(launcher_pid, victim), time.monotonic()
        if not _wait(lambda: respawned(launcher_pid, victim, old), 120):
            rec.problems.append(f"{victim} was not respawned")
            return rec
        rec.respawn_seconds = round(time.monotonic() - t, 1)
        if victim != "datagen":
            res = c.result(timeout=timeout)
            rec.run_reason = res.reason
            if not (res.accepted and res.reason == "OK"):
                rec.problems.append(f"run ended {res.reason}: {res.message}")
    finally:
        c.close()
    files = _check(rec, out, first_index)
    if victim == "datagen":
        rec.run_reason = "KILLED"
        if stop_recording is not None and not stop_recording():
            rec.problems.append("the orphaned recording did not stop")
        if files is not None and files.attempts < rec.in_flight - first_index:
            rec.problems.append(f"{rec.in_flight - first_index} attempts were reported done, the files hold {files.attempts}")
    elif files is not None:
        rec.stage_failures = sum(r in IN_FLIGHT_REASONS[victim] for r in files.after(rec.in_flight).values())
        if rec.in_flight not in files.reasons:
            rec.problems.append(f"the attempt in flight ({rec.in_flight}) is in neither file")
        if rec.successes_after < 1:
            rec.problems.append("no success after the kill")
    try:
        rec.bag_messages, rec.bag_recovered = bag_messages(out / "bag")
        if rec.bag_messages == 0:
            rec.problems.append("the bag holds no message")
        if rec.bag_messages < rec.bag_on_disk_at_kill:
            rec.problems.append(f"the recovered bag holds {rec.bag_messages} messages, fewer than the "
                                f"{rec.bag_on_disk_at_kill} on disk when the recorder died")
        if rec.bag_recovered != (victim == "recorder"):
            rec.problems.append(f"bag recovered={rec.bag_recovered} after killing {victim}")
    except Exception as e:  # noqa: BLE001 -- any reader error is a lost bag
        rec.problems.append(f"bag: {type(e).__name__}: {e}")
    return rec


def stop_recording(domain: int) -> bool:
    """Ask the graph's recorder on `domain` to stop (kill_mid_run's stop_recording: after a killed
    datagen, its orphaned recording is ended this way); True if it said so."""
    from skillgen_interfaces.srv import Recorder

    from ..answered import first_answer
    from ..nodes.latest import wait_future
    from .handles import spinning_node

    with spinning_node(domain, "chaos_recorder_stop") as node:
        cli = node.create_client(Recorder, "recorder/stop")
        if not cli.wait_for_service(timeout_sec=60):
            return False
        r = first_answer(lambda: cli.call_async(Recorder.Request()), wait_future, timeout=60, each=20)
        return r is not None and r.success

"""A generation run: validate the request, run attempts, route them to the dataset, report.

The same loop serves the datagen node (env = the ROS graph), `skillgen generate --in-process`
and bench/datagen (env = SimGenerationEnv). Attempts are independent given (seed, index), so a
run over indices [first_index, first_index + attempts) can be split into shards and merged with
core.dataset.hdf5.merge_datasets. Every success is flushed to demo.hdf5 as it happens: a run that
dies leaves a valid partial dataset.
"""
from __future__ import annotations

import dataclasses
import os
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

from ..errors import InvalidInputError, UnknownTaskError
from ..skills.augmentation import AugmentationConfig
from ..skills.segment import SourceDemo
from .attempt import METHODS, AttemptAborted, AttemptResult, GenerationConfig, GenerationEnv, run_attempt
from .profile import DEFAULT_PROFILE, get_profile
from .release import ReleaseConfig
from .selection import ALIASES as SELECTION_ALIASES, make_strategy


@dataclass(frozen=True)
class RunRequest:
    """What the user asks for (the Generate action's goal, as a core value)."""

    task: str = "Square"
    variant: str = "D1"
    method: str = "skillgen"
    attempts: int = 50
    target_successes: int = 0  # > 0: stop once this many succeeded (attempts is then a cap)
    seed: int = 0
    first_index: int = 0
    augment: bool = False
    augment_translation: float = 0.08
    augment_rotation_deg: float = 80.0
    action_noise: float = 0.05
    selection: str = "random"
    output_dir: str = "out/run"
    source_demos: str = ""  # directory of source bags; "" = bags/<task>
    max_steps: int = 3000
    video_attempts: int = 4  # attempts in attempts.mp4 (0: no videos; else also one clip per outcome); only
    # with the report (run_generation's write_report), which links them
    # skillgen: initiation poses tried per skill; 0 = the profile's (paper 1, skillgen_ros 6)
    initiation_candidates: int = 0
    release: ReleaseConfig = ReleaseConfig()  # how the hand lets go before a planned motion (release.py)
    profile: str = DEFAULT_PROFILE  # "paper" or "skillgen_ros" (profile.py)
    observation_source: str = "ground_truth"  # obs/<id>_pose: the sim's true poses, or "estimate" (a real robot)

    def config(self) -> GenerationConfig:
        """The attempt settings, with the profile applied; `paper` refuses a candidate count other than 1."""
        prof = get_profile(self.profile)
        n = self.initiation_candidates or prof.initiation_candidates
        if prof.name == "paper" and n != 1:
            raise InvalidInputError(f"the paper profile tries one initiation pose per skill; initiation_candidates={n} "
                                    "needs --profile skillgen_ros", reason="INVALID_PARAMETER")
        return GenerationConfig(variant=self.variant, action_noise=self.action_noise,
                                selection=SELECTION_ALIASES.get(self.selection, self.selection),
                                augment=self.augment,
                                augmentation=AugmentationConfig(self.augment_translation, self.augment_rotation_deg),
                                max_steps=self.max_steps, initiation_candidates=n,
                                release=self.release if prof.release_moves else self.release.without_moves(),
                                check_collisions=prof.check_collisions, profile=prof.name,
                                planner_extras=prof.planner_extras,
                                observation_source=self.observation_source)


def validate_request(req: RunRequest, known_tasks: Sequence[str], check_output: bool = True) -> None:
    """Raise a SkillGenError with a reason code for anything wrong with the request itself
    (check_output=False: a resumed distributed run, whose output dir holds its data already)."""
    if req.task not in known_tasks:
        raise UnknownTaskError(f"unknown task {req.task!r}; known: {', '.join(known_tasks)}")
    if req.method not in METHODS:
        raise InvalidInputError(f"unknown method {req.method!r}; known: {', '.join(METHODS)}", reason="UNKNOWN_METHOD")
    if req.attempts <= 0:
        raise InvalidInputError(f"attempts must be > 0, got {req.attempts}", reason="INVALID_ATTEMPTS")
    if req.target_successes < 0:
        raise InvalidInputError(f"target_successes must be >= 0, got {req.target_successes}",
                                reason="INVALID_ATTEMPTS")
    if req.seed < 0 or req.first_index < 0:
        raise InvalidInputError("seed and first_index must be >= 0", reason="INVALID_SEED")
    make_strategy(req.selection)  # raises for an unknown strategy
    req.config()  # raises for invalid noise / augmentation values
    if check_output:
        check_output_dir(req.output_dir)


def check_output_dir(path: str) -> None:
    """The run writes here; fail before any attempt if it cannot (never damage existing files)."""
    p = Path(path)
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InvalidInputError(f"cannot create output directory {p}: {e.strerror}", reason="UNWRITABLE_OUTPUT") from e
    if not os.access(p, os.W_OK | os.X_OK):
        raise InvalidInputError(f"output directory {p} is not writable", reason="UNWRITABLE_OUTPUT")
    for name in ("demo.hdf5", "failed.hdf5", "report.md", "report.html"):
        if (p / name).exists():
            raise InvalidInputError(f"{p / name} already exists; choose a new output_dir (existing data is kept)",
                                    reason="OUTPUT_EXISTS")


@dataclass(frozen=True)
class Progress:
    attempts: int
    successes: int
    total: int
    rate: float
    eta_seconds: float
    last_reason: str


@dataclass
class RunResult:
    """Counts, files and per-attempt results. A result's `episode` is None once the dataset holds it
    (unless run_generation was asked to keep them): a long run must not keep every attempt's
    arrays in memory (issue 19's soak: +0.3 MiB per attempt)."""

    request: RunRequest
    results: list[AttemptResult] = field(default_factory=list)
    failures: Counter = field(default_factory=Counter)
    dataset_path: str = ""
    failed_path: str = ""
    report_path: str = ""
    html_path: str = ""
    video_path: str = ""
    wall_seconds: float = 0.0
    stopped_early: str = ""  # why the run ended before its attempts ran out ("" = it did not)

    @property
    def attempts(self) -> int:
        return len(self.results)

    @property
    def successes(self) -> int:
        return sum(r.success for r in self.results)


def run_generation(env: GenerationEnv, demos: Sequence[SourceDemo], task, req: RunRequest,
                   on_progress: Callable[[Progress], None] | None = None,
                   should_stop: Callable[[], str] | None = None, write_report: bool = True,
                   keep_timings: bool = True, before_attempt: Callable[[int], None] | None = None,
                   keep_episodes: bool = False) -> RunResult:
    """Run the request's attempts over `env`; returns counts, files and the per-attempt results.

    should_stop() returning a non-empty reason ends the run at the running attempt's next step or env
    call; that attempt is abandoned, not written (a resumed run runs its index again);
    before_attempt(k) runs before the k-th attempt of the run (e.g. to record only some of them).
    Each attempt's Episode is dropped from its result once the sink wrote it, except those the
    videos render (keep_episodes=True keeps them all, for tests that compare attempts' arrays).
    """
    from ..dataset.report import RunSummary, write_report as _write_report
    from ..dataset.sink import AttemptSink, make_env_args

    if not demos:
        raise InvalidInputError("no source demos", reason="NO_SOURCE_DEMOS")
    cfg = req.config()
    out = RunResult(req)
    t0 = time.perf_counter()
    env_args = make_env_args(req.task, req.variant, req.method, req.seed, cfg, [o.id for o in task.objects],
                             [d.source for d in demos])
    outcomes: set[str] = set()
    with AttemptSink(req.output_dir, env_args, keep_timings=keep_timings) as sink:
        out.dataset_path, out.failed_path = sink.dataset_path, sink.failed_path
        for k in range(req.attempts):
            stop = should_stop() if should_stop else ""
            if stop:
                out.stopped_early = stop
                break
            index = req.first_index + k
            if before_attempt:
                before_attempt(k)
            try:
                r = run_attempt(env, demos, task, req.method, index, req.seed, cfg, should_abort=should_stop)
            except AttemptAborted as e:  # a stop mid-attempt: that attempt is not written
                out.stopped_early = e.reason
                break
            sink.add(r)
            # the videos re-render the first video_attempts attempts and each outcome's first (clips.py)
            filmed = req.video_attempts > 0 and (k < req.video_attempts or r.reason.value not in outcomes)
            outcomes.add(r.reason.value)
            out.results.append(r if keep_episodes or filmed else dataclasses.replace(r, episode=None))
            out.failures[r.reason.value] += 0 if r.success else 1
            done, succ = len(out.results), out.successes
            elapsed = time.perf_counter() - t0
            remaining = (req.attempts - done) if not req.target_successes else \
                min(req.attempts - done, (req.target_successes - succ) / max(succ / done, 1e-3))
            if on_progress:
                on_progress(Progress(done, succ, req.attempts, succ / done, elapsed / done * max(remaining, 0),
                                     r.reason.value))
            if req.target_successes and succ >= req.target_successes:
                break
    out.wall_seconds = time.perf_counter() - t0
    paths = {"dataset": out.dataset_path, "failed": out.failed_path}
    bag = os.path.join(req.output_dir, "bag")
    if os.path.isdir(bag):  # datagen records the session there (Generate.record_bag)
        paths["bag"] = bag
    if write_report and out.results:  # videos too: the report is what shows them
        from ..dataset.report_html import write_report_html

        videos = _videos(req, out.results)
        if videos.attempts_mp4:
            out.video_path = paths["video"] = videos.attempts_mp4
        summary = RunSummary.from_results(req.task, req.variant, req.method, out.results, req.augment,
                                          out.wall_seconds, paths, profile=cfg.profile)
        out.report_path = _write_report(req.output_dir, [summary])
        plots = {k: os.path.join(req.output_dir, f) for k, f in
                 (("success", "success_rate.png"), ("failures", "failures.png"), ("timing", "timing.png"))}
        out.html_path = write_report_html(req.output_dir, summary, out.results, videos, plots)
    return out


def _videos(req: RunRequest, results: Sequence[AttemptResult]):
    """attempts.mp4 and one clip per outcome, re-rendered at 480p from the attempts' arrays."""
    from ..dataset.clips import RunVideos, write_run_videos

    if req.video_attempts <= 0 or not results:
        return RunVideos()
    return write_run_videos(req.output_dir, req.task, req.variant, results, req.video_attempts)

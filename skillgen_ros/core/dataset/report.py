"""Run reports: success rate with its Wilson 95% interval, failure breakdown, timings, and the
paper's numbers beside ours. Markdown plus PNG plots (matplotlib, Agg backend)."""
from __future__ import annotations

import os
from collections import Counter
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from scipy.stats import binomtest

from ..errors import InvalidInputError
from ..generation.attempt import AttemptResult, FailureReason
from .paper import paper_rate

STAGES = ("reset", "perception", "motion", "skill", "success")


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval for a binomial proportion; (0, 1) when n == 0."""
    if n < 0 or not (0 <= successes <= max(n, 0)):
        raise InvalidInputError(f"wilson_interval needs 0 <= successes <= n, got {successes}/{n}")
    if n == 0:
        return 0.0, 1.0
    ci = binomtest(int(successes), int(n)).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)


@dataclass(frozen=True)
class RunSummary:
    task: str
    variant: str
    method: str
    augment: bool
    attempts: int
    successes: int
    failures: dict  # reason -> count (OK excluded)
    attempt_seconds: tuple[float, ...]
    stage_seconds: dict  # stage -> tuple of per-attempt seconds
    wall_seconds: float = 0.0
    paths: dict = field(default_factory=dict)  # "dataset", "failed", "bag", "video" -> path
    profile: str = ""  # the algorithm profile (core/generation/profile.py), shown in the label

    @property
    def rate(self) -> float:
        return self.successes / self.attempts if self.attempts else 0.0

    @property
    def label(self) -> str:
        return (f"{self.method}{'+IA' if self.augment else ''} {self.task} {self.variant}"
                + (f" [{self.profile}]" if self.profile else ""))

    @staticmethod
    def from_results(task: str, variant: str, method: str, results: Sequence[AttemptResult], augment: bool = False,
                     wall_seconds: float = 0.0, paths: dict | None = None, profile: str = "") -> "RunSummary":
        fails = Counter(r.reason.value for r in results if r.reason is not FailureReason.OK)
        return RunSummary(task, variant, method, augment, len(results), sum(r.success for r in results),
                          dict(sorted(fails.items())), tuple(r.timings.get("total", 0.0) for r in results),
                          {s: tuple(r.timings.get(s, 0.0) for r in results) for s in STAGES},
                          wall_seconds, dict(paths or {}), profile)


def _plots(out_dir: str, runs: Sequence[RunSummary]) -> dict[str, str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = {}
    labels = [r.label for r in runs]
    x = np.arange(len(runs))

    fig, ax = plt.subplots(figsize=(max(4, 1.2 * len(runs) + 2), 3.5))
    rates = np.array([100 * r.rate for r in runs])
    ci = np.array([wilson_interval(r.successes, r.attempts) for r in runs]) * 100
    ax.bar(x, rates, yerr=[rates - ci[:, 0], ci[:, 1] - rates], capsize=4, color="tab:blue")
    ax.set_xticks(x, labels, rotation=20, ha="right")
    ax.set_ylabel("success rate (%)")
    ax.set_ylim(0, 100)
    ax.set_title("Generation success (Wilson 95% CI)")
    paths["success"] = _save(fig, out_dir, "success_rate.png")

    reasons = sorted({k for r in runs for k in r.failures})
    fig, ax = plt.subplots(figsize=(max(4, 1.2 * len(runs) + 2), 3.5))
    bottom = np.zeros(len(runs))
    for reason in reasons:
        v = np.array([r.failures.get(reason, 0) for r in runs], float)
        ax.bar(x, v, bottom=bottom, label=reason)
        bottom += v
    ax.set_xticks(x, labels, rotation=20, ha="right")
    ax.set_ylabel("failed attempts")
    ax.set_title("Failure breakdown")
    if reasons:
        ax.legend(fontsize=7)
    paths["failures"] = _save(fig, out_dir, "failures.png")

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.5))
    for r in runs:
        if r.attempt_seconds:
            a1.hist(r.attempt_seconds, bins=20, alpha=0.6, label=r.label)
    a1.set_xlabel("seconds per attempt")
    a1.set_title("Time per attempt")
    if runs:
        a1.legend(fontsize=7)
    w = 0.8 / max(1, len(runs))
    for i, r in enumerate(runs):
        means = [float(np.mean(r.stage_seconds.get(s) or [0.0])) for s in STAGES]
        a2.bar(np.arange(len(STAGES)) + i * w, means, w, label=r.label)
    a2.set_xticks(np.arange(len(STAGES)) + 0.4 - w / 2, STAGES)
    a2.set_ylabel("mean seconds")
    a2.set_title("Time per stage")
    if runs:
        a2.legend(fontsize=7)
    paths["timing"] = _save(fig, out_dir, "timing.png")
    return paths


def _save(fig, out_dir: str, name: str) -> str:
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path = os.path.join(out_dir, name)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{x:.1f}"


def render_markdown(runs: Sequence[RunSummary], plots: dict[str, str], title: str) -> str:
    lines = [f"# {title}", "", "| run | attempts | successes | rate % | 95% CI % | paper % | s/attempt |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for r in runs:
        lo, hi = wilson_interval(r.successes, r.attempts)
        mean_t = float(np.mean(r.attempt_seconds)) if r.attempt_seconds else 0.0
        lines.append(f"| {r.label} | {r.attempts} | {r.successes} | {100 * r.rate:.1f} | "
                     f"{100 * lo:.1f}-{100 * hi:.1f} | {_pct(paper_rate(r.task, r.variant, r.method, r.augment))} | "
                     f"{mean_t:.3f} |")
    lines += ["", "## Failures", "", "| run | " + " | ".join(["reason", "count"]) + " |", "|---|---|---:|"]
    for r in runs:
        for reason, n in r.failures.items():
            lines.append(f"| {r.label} | {reason} | {n} |")
    lines += ["", "## Time per stage (mean seconds per attempt)", "",
              "| run | " + " | ".join(STAGES) + " | wall s |", "|---|" + "---:|" * (len(STAGES) + 1)]
    for r in runs:
        cells = [f"{float(np.mean(r.stage_seconds.get(s) or [0.0])):.4f}" for s in STAGES]
        lines.append(f"| {r.label} | " + " | ".join(cells) + f" | {r.wall_seconds:.1f} |")
    methods = sorted({(r.method, r.augment) for r in runs})
    if len(methods) > 1:
        cells = sorted({(r.task, r.variant) for r in runs})
        head = [f"{m}{'+IA' if a else ''}" for m, a in methods]
        lines += ["", "## Comparison with the paper (success %, ours / paper)", "",
                  "| task | variant | " + " | ".join(head) + " |", "|---|---|" + "---|" * len(head)]
        for task, variant in cells:
            row = []
            for m, a in methods:
                r = next((r for r in runs if (r.task, r.variant, r.method, r.augment) == (task, variant, m, a)), None)
                ours = "-" if r is None else f"{100 * r.rate:.1f}"
                row.append(f"{ours} / {_pct(paper_rate(task, variant, m, a))}")
            lines.append(f"| {task} | {variant} | " + " | ".join(row) + " |")
    paths = sorted({p for r in runs for p in r.paths.items()})
    if paths:
        lines += ["", "## Files", ""] + [f"- {k}: `{v}`" for k, v in paths]
    lines += ["", "## Plots", ""] + [f"![{k}]({os.path.basename(p)})" for k, p in plots.items()]
    return "\n".join(lines) + "\n"


def write_report(out_dir: str, runs: Sequence[RunSummary], title: str = "SkillGen data generation") -> str:
    """Write report.md and its PNGs into out_dir; returns the markdown path."""
    if not runs:
        raise InvalidInputError("write_report needs at least one run summary")
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, "report.md")
    if os.path.exists(path):  # created, never overwritten (issue 19)
        raise InvalidInputError(f"{path} already exists; reports are never overwritten", reason="OUTPUT_EXISTS")
    plots = _plots(out_dir, runs)
    with open(path, "x") as f:
        f.write(render_markdown(runs, plots, title))
    return path

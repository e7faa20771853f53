"""report.html: one run on one page, for a person deciding whether the run is any good.

Self-contained: styles, script and plots are inside the file (no network, no external asset);
the videos, dataset and bag it links are files of the run directory, by relative path, so the
directory can be moved or served as a whole. Written beside report.md, never over a file.
"""
from __future__ import annotations

import base64
import html
import os
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import InvalidInputError
from ..generation.attempt import AttemptResult
from .clips import RunVideos
from .paper import paper_rate
from .report import STAGES, RunSummary, wilson_interval

REPORT_HTML = "report.html"


@dataclass(frozen=True)
class AttemptRow:
    index: int
    success: bool
    reason: str
    source_demos: tuple[int, ...]
    seconds: float
    message: str

    @staticmethod
    def of(r: AttemptResult) -> "AttemptRow":
        return AttemptRow(r.index, bool(r.success), r.reason.value, tuple(int(d) for d in r.source_demos),
                          float(r.timings.get("total", 0.0)), r.message)


_CSS = """body{font-family:system-ui,sans-serif;margin:1.5em;max-width:1100px;color:#222}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}
td.l,th.l{text-align:left}.ok{color:#176d17}.fail{color:#b01c1c}video{width:480px;max-width:100%;background:#000}
.clips{display:flex;flex-wrap:wrap;gap:1em}.clips figure{margin:0}.big{font-size:1.6em;font-weight:600}"""
_JS = """function filterReason(v){let n=0;for(const tr of document.querySelectorAll('#attempts tbody tr')){
const show=(v===''||tr.dataset.reason===v);tr.style.display=show?'':'none';n+=show?1:0;}
document.getElementById('shown').textContent=n;}"""


def _e(x) -> str:
    return html.escape(str(x), quote=True)


def _rel(path: str, out_dir: str) -> str:
    return os.path.relpath(path, out_dir) if path else ""


def _png(path: str) -> str:
    with open(path, "rb") as f:
        return "data:image/png;base64," + base64.b64encode(f.read()).decode()


def _summary(s: RunSummary) -> str:
    lo, hi = wilson_interval(s.successes, s.attempts)
    paper = paper_rate(s.task, s.variant, s.method, s.augment)
    return (f'<p class="big">{100 * s.rate:.1f}% <small>({s.successes}/{s.attempts})</small></p>'
            f"<p>95% Wilson interval {100 * lo:.1f}-{100 * hi:.1f}%; the paper: "
            f"{'not reported' if paper is None else f'{paper:.1f}%'} ({_e(s.label)}); wall {s.wall_seconds:.1f} s</p>")


def _failures(s: RunSummary, videos: RunVideos, out_dir: str) -> str:
    rows = "".join(f'<tr><td class="l">{_e(k)}</td><td>{v}</td></tr>' for k, v in s.failures.items())
    figs = []
    for reason, index in sorted(videos.examples.items()):
        clip = videos.clips.get(index)
        if clip:
            figs.append(f'<figure><video controls muted preload="auto" src="{_e(_rel(clip, out_dir))}"></video>'
                        f"<figcaption>{_e(reason)}: attempt {index}</figcaption></figure>")
    table = f'<table><tr><th class="l">reason</th><th>attempts</th></tr>{rows}</table>' if rows else "<p>none</p>"
    return f'<h2>Failures</h2>{table}<h3>One clip per outcome</h3><div class="clips">{"".join(figs)}</div>'


def _stages(s: RunSummary) -> str:
    head = "".join(f"<th>{st}</th>" for st in STAGES)
    cells = {f: "".join(f"<td>{f_(np.asarray(s.stage_seconds.get(st) or [0.0])):.3f}</td>" for st in STAGES)
             for f, f_ in (("mean", np.mean), ("median", np.median), ("max", np.max))}
    rows = "".join(f'<tr><td class="l">{k}</td>{v}</tr>' for k, v in cells.items())
    return f'<h2>Time per stage (s per attempt)</h2><table><tr><th class="l"></th>{head}</tr>{rows}</table>'


def _attempts(rows: Sequence[AttemptRow], videos: RunVideos, out_dir: str) -> str:
    reasons = sorted({r.reason for r in rows})
    opts = "".join(f'<option value="{_e(r)}">{_e(r)}</option>' for r in reasons)
    body = []
    for r in rows:
        clip = videos.clips.get(r.index)
        link = f'<a href="{_e(_rel(clip, out_dir))}">clip</a>' if clip else ""
        demos = ", ".join(map(str, r.source_demos)) or "-"
        body.append(f'<tr data-reason="{_e(r.reason)}"><td>{r.index}</td><td class="l">{_e(demos)}</td>'
                    f'<td class="l {"ok" if r.success else "fail"}">'
                    f'{_e(r.reason)}</td><td>{r.seconds:.2f}</td><td class="l">{_e(r.message[:160])}</td>'
                    f"<td>{link}</td></tr>")
    return (f'<h2>Attempts</h2><label>reason <select id="reason" onchange="filterReason(this.value)">'
            f'<option value="">all</option>{opts}</select></label> <span id="shown">{len(rows)}</span> shown'
            '<table id="attempts"><thead><tr><th>index</th><th class="l">source demos</th><th class="l">reason</th>'
            f'<th>seconds</th><th class="l">message</th><th></th></tr></thead><tbody>{"".join(body)}</tbody></table>')


def render_html(summary: RunSummary, rows: Sequence[AttemptRow], videos: RunVideos, out_dir: str,
                plots: dict[str, str] | None = None) -> str:
    links = dict(summary.paths)
    if videos.attempts_mp4:
        links["video"] = videos.attempts_mp4
    files = "".join(f'<li>{_e(k)}: <a href="{_e(_rel(v, out_dir))}">{_e(_rel(v, out_dir))}</a></li>'
                    for k, v in sorted(links.items()) if v)
    main_video = (f'<video controls muted preload="auto" src="{_e(_rel(videos.attempts_mp4, out_dir))}"></video>'
                  if videos.attempts_mp4 else "")
    imgs = "".join(f'<img alt="{_e(k)}" src="{_png(p)}">' for k, p in (plots or {}).items() if os.path.isfile(p))
    return (f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>{_e(summary.label)}</title>'
            f"<style>{_CSS}</style><script>{_JS}</script></head><body><h1>{_e(summary.label)}</h1>"
            f"{_summary(summary)}{main_video}{_failures(summary, videos, out_dir)}{_stages(summary)}"
            f"{_attempts(rows, videos, out_dir)}<h2>Files</h2><ul>{files}</ul>{imgs}</body></html>\n")


def write_report_html(out_dir: str, summary: RunSummary, results: Sequence[AttemptResult],
                      videos: RunVideos = RunVideos(), plots: dict[str, str] | None = None) -> str:
    """Write report.html into out_dir (created, never overwritten); returns its path."""
    path = os.path.join(out_dir, REPORT_HTML)
    if os.path.exists(path):
        raise InvalidInputError(f"{path} already exists; reports are never overwritten", reason="OUTPUT_EXISTS")
    text = render_html(summary, [AttemptRow.of(r) for r in results], videos, out_dir, plots)
    with open(path, "x", encoding="utf-8") as f:
        f.write(text)
    return path

"""report.html and the run videos: H.264 at 480p, one clip per outcome, the attempts table with
its reason filter, checked as a browser sees it (headless Chromium, Debian's package)."""
from __future__ import annotations

import json
import os
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pytest

from _chromium import CHROMIUM, inspect_page
from skillgen_ros.core.dataset.clips import write_run_videos
from skillgen_ros.core.dataset.render import ClipSpec
from skillgen_ros.core.dataset.report import RunSummary, write_report
from skillgen_ros.core.dataset.report_html import write_report_html
from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.generation.attempt import AttemptResult
from skillgen_ros.core.generation.episode import Episode
from skillgen_ros.core.generation.outcome import FailureReason
from skillgen_ros.core.robot import Q_HOME
from skillgen_ros.core.sim.world import SimWorld

TASK, VARIANT = "Square", "D0"


def _episode(seed: int, steps: int) -> Episode:
    w = SimWorld()
    try:
        scene = w.reset(TASK, VARIANT, seed)
        poses = {o.id: p.as_array() for o, p in zip(scene.objects, [scene.poses[o.id] for o in scene.objects])}
    finally:
        w.close()
    q = Q_HOME + np.outer(np.arange(steps) / max(steps, 1), [0.4, 0.2, 0, 0.2, 0, 0, 0])
    obs = {"robot0_joint_pos": q, "robot0_gripper_qpos": np.full((steps, 2), 0.04)}
    for oid, p in poses.items():
        obs[f"{oid}_pose"] = np.tile(p, (steps, 1))
    return Episode(obs=obs, actions=np.zeros((steps, 7)), actions_abs=np.zeros((steps, 8)), states=np.zeros((steps, 1)),
                   rewards=np.zeros(steps), dones=np.zeros(steps), labels={}, object_ids=tuple(sorted(poses)))


def _results() -> list[AttemptResult]:
    spec = [(FailureReason.OK, 20), (FailureReason.PLAN_FAILED, 0), (FailureReason.OK, 12), (FailureReason.SKILL_FAILED, 9)]
    return [AttemptResult(i, "skillgen", reason is FailureReason.OK, reason, f"attempt {i} <b>{reason.value}</b>", i,
                          (i % 3, 1), _episode(i, steps), {"total": 1.5 + i, "motion": 0.5, "skill": 1.0 + i})
            for i, (reason, steps) in enumerate(spec)]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    results = _results()
    videos = write_run_videos(str(out), TASK, VARIANT, results, first_n=2, spec=ClipSpec(max_frames=8))
    (out / "demo.hdf5").write_bytes(b"")
    summary = RunSummary.from_results(TASK, VARIANT, "skillgen", results, wall_seconds=9.0,
                                      paths={"dataset": str(out / "demo.hdf5")})
    write_report(str(out), [summary])
    plots = {"success": str(out / "success_rate.png")}
    write_report_html(str(out), summary, results, videos, plots)
    return out, videos


def test_videos_are_h264_480p_one_clip_per_outcome(run_dir):
    out, videos = run_dir
    assert videos.examples == {"OK": 0, "PLAN_FAILED": 1, "SKILL_FAILED": 3}
    assert sorted(videos.clips) == [0, 1, 3]  # the first two attempts and one per outcome, each rendered once
    for path in [videos.attempts_mp4, *videos.clips.values()]:
        reader = imageio_ffmpeg.read_frames(path)
        meta = next(reader)
        reader.close()
        assert meta["codec"].startswith("h264") and tuple(meta["size"]) == (640, 480), meta
        with open(path, "rb") as f:
            head = f.read(64 * 1024)
        assert head.find(b"moov") < head.find(b"mdat") or b"mdat" not in head  # +faststart: index first


def test_report_html_content_and_never_overwritten(run_dir):
    out, videos = run_dir
    text = (out / "report.html").read_text()
    assert (out / "report.md").exists()
    for s in ("50.0%", "Wilson interval", "the paper: ", '<option value="PLAN_FAILED">', 'data-reason="SKILL_FAILED"',
              "clips/attempt_1.mp4", 'href="demo.hdf5"', 'href="attempts.mp4"', "data:image/png;base64,",
              "&lt;b&gt;OK&lt;/b&gt;"):
        assert s in text, s
    assert "<b>OK</b>" not in text and "http://" not in text and "https://" not in text  # escaped; nothing remote
    # the interval and the paper's cell for Square D0 skillgen, the time per stage (reset, perception, motion,
    # skill, success: mean and max over the four attempts), an attempt's row (index, source demos, reason, seconds)
    for s in ("95% Wilson interval 15.0-85.0%", "the paper: 99.8%", "<h2>Time per stage (s per attempt)</h2>",
              '<td class="l">mean</td><td>0.000</td><td>0.000</td><td>0.500</td><td>2.500</td><td>0.000</td>',
              '<td class="l">max</td><td>0.000</td><td>0.000</td><td>0.500</td><td>4.000</td><td>0.000</td>',
              '<tr data-reason="PLAN_FAILED"><td>1</td><td class="l">1, 1</td><td class="l fail">PLAN_FAILED</td>'
              "<td>2.50</td>"):
        assert s in text, s
    with pytest.raises(InvalidInputError) as e:
        write_report_html(str(out), RunSummary.from_results(TASK, VARIANT, "skillgen", []), [])
    assert e.value.reason == "OUTPUT_EXISTS"


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (scripts/bootstrap.sh installs "
                                              "Debian's chromium package; CI runs it)")
def test_report_plays_in_headless_chromium(run_dir):
    out, videos = run_dir
    shown = "document.getElementById('shown').textContent"
    report = inspect_page(out / "report.html", out / "report_screenshot.png", evaluate=(
        f"filterReason('PLAN_FAILED'); {shown}", f"filterReason('OK'); {shown}", f"filterReason(''); {shown}"))
    assert report.console_errors == []
    assert report.values == ["1", "2", "4"]  # the reason filter, as a user's select would drive it
    assert len(report.videos) == 1 + len(videos.examples)
    for v in report.videos:
        assert v["error"] == 0 and v["readyState"] >= 2 and (v["width"], v["height"]) == (640, 480), v
        assert v["frames"] >= 1, v  # decoded frames (getVideoPlaybackQuality)
    assert report.screenshot.stat().st_size > 10_000 and report.screenshot.read_bytes()[:4] == b"\x89PNG"

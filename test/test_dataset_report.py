"""Wilson interval, the markdown/PNG report, the paper's table, and MP4 clips."""
import os

import cv2
import numpy as np
import pytest
from _generation_fakes import FakeTask, FakeWorld, make_source_demos

from skillgen_ros.core.dataset.paper import AVERAGE, PAPER_RATES, paper_rate
from skillgen_ros.core.dataset.report import RunSummary, render_markdown, wilson_interval, write_report
from skillgen_ros.core.dataset.video import attempt_clip, caption, write_mp4
from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.generation.attempt import GenerationConfig, run_attempt


@pytest.mark.parametrize("k,n,lo,hi", [(8, 10, 0.4902, 0.9433), (0, 10, 0.0, 0.2775), (10, 10, 0.7225, 1.0),
                                       (50, 100, 0.4038, 0.5962), (1, 1, 0.2065, 1.0)])
def test_wilson_known_values(k, n, lo, hi):
    a, b = wilson_interval(k, n)
    assert a == pytest.approx(lo, abs=1e-4) and b == pytest.approx(hi, abs=1e-4)


def test_wilson_edge_cases():
    assert wilson_interval(0, 0) == (0.0, 1.0)
    with pytest.raises(InvalidInputError):
        wilson_interval(3, 2)


def test_paper_table():
    assert paper_rate("square", "D2", "skillgen") == 87.7 and paper_rate("square", "D2", "mimicgen") == 31.8
    assert paper_rate("square", "D0", "skillgen", augment=True) == 30.7
    assert paper_rate("coffee", "clutter", "skillgen") == pytest.approx(55.0)  # the D1-clutter row
    assert paper_rate("square", "clutter", "skillgen") == pytest.approx(62.5)
    assert paper_rate("square", "clutter", "mimicgen") == pytest.approx(4.0)
    assert paper_rate("square", "D0", "replay_noise") is None
    assert paper_rate("NutAssembly", "D1", "skillgen") == 91.7  # the task suite's CamelCase name
    core = [v["skillgen"] for (t, var), v in PAPER_RATES.items() if var in ("D0", "D1", "D2")]
    assert np.mean(core) == pytest.approx(AVERAGE["skillgen"], abs=0.1)


def test_report_from_attempts(tmp_path):
    demos = make_source_demos(2)
    runs = []
    for method in ("skillgen", "mimicgen"):
        res = [run_attempt(FakeWorld(plan_status="OK" if i % 3 else "PLAN_FAILED"), demos, FakeTask(),
                           method, i, 3, GenerationConfig(variant="D1")) for i in range(6)]
        runs.append(RunSummary.from_results("square", "D1", method, res, paths={"dataset": "out/demo.hdf5"}))
    assert runs[0].attempts == 6 and runs[0].successes == 4 and runs[0].failures == {"PLAN_FAILED": 2}
    assert runs[1].successes == 6  # mimicgen never calls the planner
    path = write_report(str(tmp_path), runs)
    text = open(path).read()
    assert "| skillgen square D1 | 6 | 4 | 66.7 |" in text and "91.5" in text
    assert "Comparison with the paper" in text and "100.0 / 48.9" in text
    for png in ("success_rate.png", "failures.png", "timing.png"):
        p = tmp_path / png
        assert p.exists() and p.read_bytes()[:4] == b"\x89PNG" and f"({png})" in text
    single = render_markdown(runs[:1], {}, "t")
    assert "Comparison with the paper" not in single
    with pytest.raises(InvalidInputError):
        write_report(str(tmp_path), [])


def test_mp4_round_trip(tmp_path):
    frames = [np.full((64, 80, 3), i * 8, np.uint8) for i in range(12)]
    p = write_mp4(str(tmp_path / "v" / "a.mp4"), frames, fps=10)
    cap = cv2.VideoCapture(p)
    n, (ok, fr) = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)), cap.read()
    cap.release()
    assert n == 12 and ok and fr.shape == (64, 80, 3)
    clip = attempt_clip(str(tmp_path / "b.mp4"), [("attempt 0", True, frames[:3]), ("attempt 1", False, frames[:2])],
                        size=(160, 128))
    assert os.path.getsize(clip) > 0
    assert caption(frames[0], "x", False).shape == frames[0].shape
    with pytest.raises(InvalidInputError):
        write_mp4(str(tmp_path / "c.mp4"), [])
    with pytest.raises(InvalidInputError):
        write_mp4(str(tmp_path / "d.mp4"), [frames[0], np.zeros((10, 10, 3), np.uint8)])

"""docs/annotations.md stays true: its examples parse and validate, and its reason codes are the code's.

Also the override checks the page documents: seconds are the demo's control time (step / 20 Hz)
and a time outside the demo is rejected like a step outside it (issue 24), never clamped.
"""
from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from skillgen_ros.cli import annotate as A
from skillgen_ros.core.errors import AnnotationError
from skillgen_ros.core.skills.annotation import (Override, apply_overrides, loads_annotation, step_times,
                                                 time_to_step, validate_annotation)
from skillgen_ros.core.skills.auto_annotation import rules_from_dict
from skillgen_ros.core.skills.bag_demos import read_annotation, read_demo_arrays
from skillgen_ros.core.tasks import get_task

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "annotations.md"


def _yaml_blocks(text: str) -> list[str]:
    return re.findall(r"```yaml\n(.*?)```", text, flags=re.S)


def test_the_format_example_is_valid_for_its_task_and_bag():
    blocks = _yaml_blocks(DOC.read_text())
    ann = loads_annotation(blocks[0], f"{DOC} (first yaml block)")
    task = get_task(ann.task)  # UNKNOWN_TASK if the doc spells the task the code does not know
    bag = ROOT / "bags" / ann.task / ann.demo
    arrays = read_demo_arrays(bag)
    validate_annotation(ann, task, num_steps=len(arrays.timestamps))
    assert ann == read_annotation(bag), "the doc says the example is the shipped annotation of that bag"


def test_the_rules_example_parses():
    rules = rules_from_dict(yaml.safe_load(_yaml_blocks(DOC.read_text())[1]))
    assert rules.rule(0).start_distance == 0.06 and rules.rule(1).post_steps == 5


def test_the_reason_codes_in_the_docs_are_the_codes_the_code_raises():
    doc = DOC.read_text()
    table = doc[doc.index("## Validation"):doc.index("## Automatic proposals")]
    documented = set(re.findall(r"`((?:ANNOTATION|BAD)_[A-Z_]+)`", table))
    src = "\n".join(p.read_text() for p in (ROOT / "skillgen_ros").rglob("*.py"))
    raised = set(re.findall(r"\"(ANNOTATION_[A-Z_]+)\"", src))
    assert raised <= documented, f"raised but not documented: {sorted(raised - documented)}"
    missing = {c for c in documented if f'"{c}"' not in src and c != "BAD_ANNOTATION"}
    assert not missing, f"documented but never raised: {sorted(missing)}"  # BAD_ANNOTATION is the class default


def test_time_overrides_are_checked_like_step_overrides():
    task = get_task("Square")
    ann = loads_annotation(_yaml_blocks(DOC.read_text())[0])
    ts = step_times(ann.num_steps)
    assert ts[20] == pytest.approx(1.0) and time_to_step(ts, 1.0) == 20  # step k at k / 20 Hz
    # the demo's last step plus one period is its end: an end edge may sit there, by step or by time
    end = ann.num_steps / 20.0
    assert apply_overrides(ann, [Override(1, "end", time=end)], ts, task).skills[1].end_step == ann.num_steps
    for bad in (Override(1, "end", time=end + 0.2), Override(1, "end", time=500.0), Override(0, "start", time=-1.0),
                Override(1, "end", step=ann.num_steps + 1), Override(0, "start", step=-3)):
        with pytest.raises(AnnotationError) as e:
            apply_overrides(ann, [bad], ts, task)
        assert e.value.reason == "ANNOTATION_OUT_OF_RANGE", bad
        assert "demo_00" in str(e.value)
    with pytest.raises(AnnotationError) as e:
        apply_overrides(ann, [Override(5, "start", step=10)], ts, task)
    assert e.value.reason == "ANNOTATION_UNKNOWN_SKILL"


def test_cli_rejects_a_time_past_the_demo_and_prints_control_time(tmp_path, capsys):
    src = ROOT / "bags" / "Square" / "demo_00"
    bag = tmp_path / src.name
    shutil.copytree(src, bag)
    before = read_annotation(bag)
    assert A.main([str(bag), "--override", "1.end=500s"]) == 1
    err = capsys.readouterr().err
    assert "ANNOTATION_OUT_OF_RANGE" in err and "500" in err
    assert read_annotation(bag) == before, "a rejected override must not touch the stored annotation"
    assert A.main([str(bag), "--override", f"0.end={(before.skills[0].end_step + 2) / 20:.2f}s"]) == 0
    out = capsys.readouterr().out
    s0 = read_annotation(bag).skills[0]
    assert s0.end_step == before.skills[0].end_step + 2
    # the summary's seconds are step / 20 Hz, the clock the override used
    assert f"t [{s0.start_step / 20:6.2f}, {s0.end_step / 20:6.2f}) s" in out
    assert np.isclose(float(re.search(r"steps, ([0-9.]+) s", out).group(1)), before.num_steps / 20)

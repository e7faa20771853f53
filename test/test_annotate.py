"""`skillgen annotate`: auto-annotation reproduces the shipped annotations; overrides; validation; bag info."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml

from skillgen_ros.cli import annotate as A
from skillgen_ros.cli.demos import subset_paths
from skillgen_ros.core.bag.info import bag_info, format_info
from skillgen_ros.core.errors import AnnotationError
from skillgen_ros.core.skills.annotation import load_annotation
from skillgen_ros.core.skills.bag_demos import read_annotation, read_demo_arrays
from skillgen_ros.core.tasks import TASK_NAMES, get_task

BAGS = Path(__file__).resolve().parents[1] / "bags"


def test_auto_annotation_of_every_shipped_demo_matches_its_stored_annotation():
    for t in TASK_NAMES:
        task, rules = get_task(t), A.rules_for(t)
        for path in subset_paths(BAGS / t, "all"):
            stored = read_annotation(path)
            assert stored is not None, f"{path} has no annotation"
            auto = A.propose(path, task, rules)
            assert auto.skills == stored.skills, f"{path}: auto {auto.skills} != stored {stored.skills}"
            assert auto.motions == stored.motions and auto.num_steps == stored.num_steps


def test_skill_spans_sit_on_the_gripper_events():
    """Grasp skills end just after the close command; placements just after the open."""
    for t in ("Square", "PickPlace"):
        path = subset_paths(BAGS / t, "all")[0]
        arrays = read_demo_arrays(path)
        ann = read_annotation(path)
        g = arrays.gripper
        grasp, place = ann.skills
        closes = [k for k in range(1, len(g)) if g[k] > 0 >= g[k - 1]]
        opens = [k for k in range(1, len(g)) if g[k] <= 0 < g[k - 1]]
        assert grasp.start_step < closes[0] < grasp.end_step
        assert place.start_step < opens[0] < place.end_step


@pytest.fixture
def bag(tmp_path) -> Path:
    src = subset_paths(BAGS / "Square", "all")[0]
    dst = tmp_path / src.name
    shutil.copytree(src, dst)
    return dst


def test_cli_writes_sidecar_with_step_and_time_overrides(bag, capsys):
    before = read_annotation(bag)
    new_start = before.skills[1].start_step + 4
    end0 = before.skills[0].start_step + 20
    assert A.main([str(bag), "--override", f"1.start={new_start}", "--override", f"0.end={end0 / 20:.2f}s"]) == 0
    ann = load_annotation(str(bag / "annotations.yaml"))
    assert ann.skills[1].start_step == new_start
    assert ann.skills[0].end_step == end0  # seconds -> step at 20 Hz
    assert ann.origin == "auto+overrides"
    assert ann.motions[1].start_step == end0 and ann.motions[1].end_step == new_start
    out = capsys.readouterr().out
    assert "skill 1" in out and str(bag) in out
    info = format_info(bag_info(bag))  # `skillgen bag info` shows the sidecar
    assert "Annotations:" in info and "sidecar annotations.yaml" in info
    # --from-existing keeps the manual edits and layers a new one on top
    assert A.main([str(bag), "--from-existing", "--override", "1.end=" + str(ann.skills[1].end_step - 1)]) == 0
    again = load_annotation(str(bag / "annotations.yaml"))
    assert again.skills[0].end_step == end0 and again.skills[1].end_step == ann.skills[1].end_step - 1


def test_cli_rejects_overrides_that_break_the_annotation(bag, capsys):
    before = read_annotation(bag)
    assert A.main([str(bag), "--override", f"1.start={before.skills[0].start_step}"]) == 1
    err = capsys.readouterr().err
    assert "ANNOTATION_OVERLAP" in err and str(bag) in err
    assert read_annotation(bag) == before, "a rejected override must not touch the stored annotation"
    assert A.main([str(bag), "--override", "0.end=99999"]) == 1
    assert "ANNOTATION_OUT_OF_RANGE" in capsys.readouterr().err
    assert A.main([str(bag), "--override", "garbage"]) == 1
    assert "BAD_OVERRIDE" in capsys.readouterr().err


def test_cli_check_reports_invalid_stored_annotations(bag, capsys):
    assert A.main([str(bag), "--check"]) == 0
    assert "reproduces it" in capsys.readouterr().out
    f = bag / "annotations.yaml"
    doc = yaml.safe_load(f.read_text())
    doc["skills"][0]["object"] = "banana"
    f.write_text(yaml.safe_dump(doc))
    assert A.main([str(bag), "--check"]) == 1
    err = capsys.readouterr().err
    assert "ANNOTATION_UNKNOWN_OBJECT" in err and "banana" in err and str(bag) in err


def test_rules_are_configurable_per_task(bag, tmp_path):
    rules = tmp_path / "rules.yaml"
    handle = A._task_rules("Square")["skills"][0]["offset"]
    rules.write_text(yaml.safe_dump({"Square": {"skills": {
        0: {"start_distance": 0.05, "post_steps": 2, "offset": handle},
        1: {"start_distance": 0.12, "post_steps": 0}}}}))
    stock = A.propose(bag, get_task("Square"), A.rules_for("Square"))
    custom = A.propose(bag, get_task("Square"), A.rules_for("Square", str(rules)))
    assert custom.skills[0].end_step == stock.skills[0].end_step - 8
    rules.write_text(yaml.safe_dump({"default": {"end_event": "nonsense"}}))
    with pytest.raises(AnnotationError) as e:
        A.rules_for("Square", str(rules))
    assert e.value.reason == "BAD_RULES"

"""Annotation format, validation errors, overrides and auto-annotation."""
import numpy as np
import pytest
from _generation_fakes import RULES, FakeTask, annotate, scripted_demo

from skillgen_ros.core.errors import AnnotationError
from skillgen_ros.core.skills.annotation import (Annotation, Override, SkillAnnotation, apply_overrides,
                                                 derive_motions, dumps_annotation, load_annotation,
                                                 loads_annotation, parse_override, save_annotation,
                                                 validate_annotation)
from skillgen_ros.core.skills.auto_annotation import rules_from_dict

TASK = FakeTask()


def ann(skills, n=100, task="pick_place"):
    skills = tuple(SkillAnnotation(*s) for s in skills)
    return Annotation(task, "demo_0", n, skills, derive_motions(skills, n))


GOOD = [(0, "cube", 20, 40), (1, "plate", 60, 80)]


def test_valid_and_motions():
    a = validate_annotation(ann(GOOD), TASK)
    assert [(m.start_step, m.end_step, m.next_skill) for m in a.motions] == [(0, 20, 0), (40, 60, 1), (80, 100, None)]


@pytest.mark.parametrize("skills,n,reason", [
    ([(0, "cube", 20, 40), (1, "plate", 60, 120)], 100, "ANNOTATION_OUT_OF_RANGE"),
    ([(0, "cube", -1, 40), (1, "plate", 60, 80)], 100, "ANNOTATION_OUT_OF_RANGE"),
    ([(0, "cube", 40, 40), (1, "plate", 60, 80)], 100, "ANNOTATION_OUT_OF_RANGE"),
    ([(0, "cube", 20, 65), (1, "plate", 60, 80)], 100, "ANNOTATION_OVERLAP"),
    ([(0, "cube", 20, 40)], 100, "ANNOTATION_MISSING_SKILL"),
    ([], 100, "ANNOTATION_MISSING_SKILL"),
    ([(0, "cube", 20, 40), (1, "bowl", 60, 80)], 100, "ANNOTATION_UNKNOWN_OBJECT"),
    ([(0, "plate", 20, 40), (1, "plate", 60, 80)], 100, "ANNOTATION_UNKNOWN_OBJECT"),
    ([(1, "plate", 20, 40), (0, "cube", 60, 80)], 100, "ANNOTATION_ORDER"),
    ([(0, "cube", 20, 40), (1, "plate", 60, 80), (2, "plate", 85, 90)], 100, "ANNOTATION_UNKNOWN_SKILL"),
])
def test_validation_errors(skills, n, reason):
    with pytest.raises(AnnotationError) as e:
        validate_annotation(ann(skills, n), TASK)
    assert e.value.reason == reason
    assert "demo_0" in str(e.value)


def test_wrong_task_and_length():
    with pytest.raises(AnnotationError) as e:
        validate_annotation(ann(GOOD, task="square"), TASK)
    assert e.value.reason == "ANNOTATION_WRONG_TASK"
    with pytest.raises(AnnotationError) as e:
        validate_annotation(ann(GOOD), TASK, num_steps=90)
    assert e.value.reason == "ANNOTATION_OUT_OF_RANGE"


def test_yaml_json_round_trip(tmp_path):
    a = ann(GOOD)
    for name in ("a.yaml", "a.json"):
        p = save_annotation(str(tmp_path / name), a)
        assert load_annotation(p) == a
    assert loads_annotation(dumps_annotation(a, "json")) == a
    # motions are derived when omitted
    text = "task: pick_place\ndemo: demo_0\nnum_steps: 100\nskills:\n" \
           "  - {index: 0, object: cube, start_step: 20, end_step: 40}\n" \
           "  - {index: 1, object: plate, start_step: 60, end_step: 80}\n"
    assert loads_annotation(text).motions == a.motions


@pytest.mark.parametrize("text,reason", [
    ("task: x\n", "BAD_ANNOTATION"),
    ("[1, 2", "BAD_ANNOTATION"),
    ("task: t\ndemo: d\nnum_steps: 10\nskills: [{index: 0, object: cube, start_step: a, end_step: 3}]\n",
     "BAD_ANNOTATION"),
])
def test_malformed_documents(text, reason):
    with pytest.raises(AnnotationError) as e:
        loads_annotation(text, "file.yaml")
    assert e.value.reason == reason and "file.yaml" in str(e.value)


def test_missing_file(tmp_path):
    with pytest.raises(AnnotationError) as e:
        load_annotation(str(tmp_path / "nope.yaml"))
    assert e.value.reason == "ANNOTATION_NOT_FOUND"


def test_overrides_by_step_and_time():
    a = ann(GOOD)
    ts = np.arange(100) * 0.05
    out = apply_overrides(a, [parse_override("0.start=15"), parse_override("1.end=4.5s")], ts, TASK)
    assert (out.skills[0].start_step, out.skills[1].end_step) == (15, 90)
    assert out.motions[0].end_step == 15 and out.origin == "manual+overrides"
    assert parse_override("1.end=12") == Override(1, "end", step=12)
    with pytest.raises(AnnotationError) as e:
        apply_overrides(a, [Override(0, "end", step=70)], ts, TASK)
    assert e.value.reason == "ANNOTATION_OVERLAP"
    for bad in ("0.middle=3", "x.start=3", "0.start", "0.start=abc"):
        with pytest.raises(AnnotationError) as e:
            parse_override(bad)
        assert e.value.reason == "BAD_OVERRIDE"


def test_auto_annotation_finds_the_skills():
    arr = scripted_demo(100)
    a = annotate(arr)
    assert a.origin == "auto" and [s.object for s in a.skills] == ["cube", "plate"]
    s0, s1 = a.skills
    # pick: starts on approach, ends 5 steps after the close event; place: ends 3 steps after the open
    close = int(np.flatnonzero(np.diff((arr.gripper > 0).astype(int)) == 1)[0]) + 1
    opened = int(np.flatnonzero(np.diff((arr.gripper > 0).astype(int)) == -1)[0]) + 1
    assert s0.start_step < close and s0.end_step == close + 6
    assert s1.start_step < opened and s1.end_step == opened + 4
    d0 = np.linalg.norm(arr.ee_positions[s0.start_step] - arr.object_positions["cube"][s0.start_step])
    assert d0 <= RULES.rule(0).start_distance


def test_auto_annotation_failures_and_rules():
    arr = scripted_demo(100)
    from skillgen_ros.core.skills.auto_annotation import auto_annotate
    from skillgen_ros.core.geometry import pose_arrays_to_matrices
    objs = {k: pose_arrays_to_matrices(arr.object_positions[k], arr.object_quaternions[k]) for k in arr.object_positions}
    with pytest.raises(AnnotationError) as e:  # gripper never closes
        auto_annotate(TASK, "d", arr.ee_positions, -np.ones(len(arr.gripper)), objs, RULES)
    assert e.value.reason == "ANNOTATION_AUTO_FAILED"
    with pytest.raises(AnnotationError) as e:
        auto_annotate(TASK, "d", arr.ee_positions, arr.gripper, {"cube": objs["cube"]}, RULES)
    assert e.value.reason == "ANNOTATION_UNKNOWN_OBJECT"
    r = rules_from_dict({"default": {"post_steps": 2}, "skills": {1: {"start_distance": 0.2, "offset": [0, 0, 0.1]}}})
    assert r.rule(0).post_steps == 2 and r.rule(1).post_steps == 2 and r.rule(1).offset == (0, 0, 0.1)
    with pytest.raises(AnnotationError) as e:
        rules_from_dict({"default": {"bogus": 1}})
    assert e.value.reason == "BAD_RULES"

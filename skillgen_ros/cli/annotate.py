"""`skillgen annotate`: propose, override and validate the skill annotation of source-demo bags.

    skillgen annotate BAG [BAG ...] [--task T] [--rules R.yaml] [--override 1.start=120] [--override 0.end=4.2s]
                      [--from-existing] [--check] [--print] [--out FILE]

Default: propose segments from gripper events and EE proximity (rules per task: TASK_RULES,
or a YAML file with `--rules`, either {default:.., skills:{i:..}} or keyed by task name), apply
`--override`s (by step, or by time from the demo's first step with an `s` suffix: step / 20 Hz),
validate, and write the sidecar
`annotations.yaml` in the bag directory (`skillgen bag info` shows it). `--from-existing`
starts from the bag's stored annotation instead of a new proposal; `--check` only validates the
stored annotation and reports whether auto-annotation reproduces it (exit 1 if not valid).
Format: docs/annotations.md.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

from skillgen_ros.core.errors import AnnotationError, SkillGenError
from skillgen_ros.core.geometry import pose_arrays_to_matrices
from skillgen_ros.core.skills.annotation import (Annotation, apply_overrides, dumps_annotation, parse_override,
                                                 save_annotation, step_times, validate_annotation)
from skillgen_ros.core.skills.auto_annotation import AnnotationRules, auto_annotate, rules_from_dict
from skillgen_ros.core.skills.bag_demos import (annotation_path, expand_bag_paths, open_bag, read_annotation,
                                                read_demo_arrays, read_scene)
from skillgen_ros.core.tasks import get_task
from skillgen_ros.core.tasks.skill_points import skill_point_offset


def _kp(task: str, index: int) -> list[float]:
    """Skill `index`'s working point in its object's frame (core/tasks/skill_points.py)."""
    return [float(v) for v in skill_point_offset(get_task(task), index)]


def _task_rules(task: str) -> dict:
    """Per-task proposal rules, matched to how demos approach each skill object (docs/source_demos.md)."""
    nut = lambda i: {i: {"start_distance": 0.05, "post_steps": 10, "offset": _kp(task, i)}}  # noqa
    # a placement ends 30 steps (1.5 s) after the open: the fingers have opened and the hand has backed off
    # most of its 10 cm, so the wrist is clear of robosuite's 13 cm peg when the next motion is planned
    peg = lambda i: {i: {"start_distance": 0.12, "post_steps": 30, "offset": _kp(task, i)}}  # noqa
    if task == "Square":
        return {"skills": {**nut(0), **peg(1)}}
    if task == "NutAssembly":
        return {"skills": {**nut(0), **peg(1), **nut(2), **peg(3)}}
    if task == "PickPlace":
        return {"skills": {0: {"start_distance": 0.06, "post_steps": 10, "offset": _kp(task, 0)},
                           1: {"start_distance": 0.21, "post_steps": 5, "offset": _kp(task, 1)}}}
    if task == "Threading":
        return {"skills": {0: {"start_distance": 0.05, "post_steps": 10, "offset": _kp(task, 0)},
                           1: {"start_distance": 0.19, "end_event": "demo_end", "offset": _kp(task, 1)}}}
    if task == "ThreePieceAssembly":
        # grasps measured to the grasp point (the demonstrator's, 2 cm below a piece's top); insertions to the
        # top of what the piece goes into (the base's top, piece 1's ridge) and ended as a nut placement, once
        # the hand has backed off (piece 2's 16 cm stack is under the wrist right after the open)
        grasp = lambda i: {i: {"start_distance": 0.05, "post_steps": 10, "offset": _kp(task, i)}}  # noqa
        insert = lambda i, d: {i: {"start_distance": d, "post_steps": 30, "offset": _kp(task, i)}}  # noqa
        return {"skills": {**grasp(0), **insert(1, 0.13), **grasp(2), **insert(3, 0.16)}}
    if task == "Coffee":
        # the pod grasp to its grasp point; the insertion from 10 cm over the holder's rim (the pod hangs 3.8 cm
        # under the hand) to the demo's end: it holds the release and the lid push that follows
        return {"skills": {0: {"start_distance": 0.05, "post_steps": 10, "offset": _kp(task, 0)},
                           1: {"start_distance": 0.10, "end_event": "demo_end", "offset": _kp(task, 1)}}}
    if task == "CoffeePreparation":
        # the mug and the pod grasps to their grasp points; placing the mug and opening the lid (two releases) from
        # 20 cm off the holder's rim (the mug slides in from 16 cm out, its rim 12 cm under the hand) until the hand
        # leaves 22 cm (on its way to the drawer); the drawer from its handle to 10 steps after the release that
        # ends the pull; the insertion as Coffee's, through the lid push to the demo's end
        holder = [float(v) for v in get_task(task).object("coffee_machine").keypoint("holder_top")]
        return {"skills": {0: {"start_distance": 0.06, "post_steps": 10, "offset": _kp(task, 0)},
                           1: {"start_distance": 0.20, "end_event": "leave", "end_distance": 0.22, "offset": holder},
                           2: {"start_distance": 0.06, "end_event": "open", "post_steps": 10, "offset": _kp(task, 2)},
                           3: {"start_distance": 0.05, "post_steps": 10, "offset": _kp(task, 3)},
                           4: {"start_distance": 0.10, "end_event": "demo_end", "offset": _kp(task, 4)}}}
    return {}


def rules_for(task: str, rules_file: str | None = None) -> AnnotationRules:
    """The task's rules: from `rules_file` (a task-keyed or plain rules YAML) or the built-in ones."""
    if rules_file:
        try:
            doc = yaml.safe_load(Path(rules_file).read_text()) or {}
        except (OSError, yaml.YAMLError) as e:
            raise AnnotationError(f"{rules_file}: cannot read rules: {e}", reason="BAD_RULES") from e
        if task in doc:
            doc = doc[task]
        return rules_from_dict(doc)
    return rules_from_dict(_task_rules(task))


def propose(path, task, rules: AnnotationRules, arrays=None) -> Annotation:
    """Auto-annotate one bag from its gripper actions and EE / object poses."""
    arrays = arrays or read_demo_arrays(path)
    objs = {k: pose_arrays_to_matrices(arrays.object_positions[k], arrays.object_quaternions[k])
            for k in arrays.object_positions}
    try:
        return auto_annotate(task, arrays.name, arrays.ee_positions, arrays.gripper, objs, rules)
    except AnnotationError as e:
        raise AnnotationError(f"{path}: {e.args[0]}", reason=e.reason) from e


def _task_of(path, name: str | None):
    if name:
        return get_task(name)
    scene = read_scene(open_bag(path))
    if scene is None:
        raise AnnotationError(f"{path}: bag has no scene record; pass --task", reason="UNKNOWN_TASK")
    return get_task(scene.task)


def _summary(ann: Annotation) -> str:
    """One line per skill; the seconds are the demo's control time (step / 20 Hz), as overrides take them."""
    ts = step_times(ann.num_steps + 1)
    rows = [f"{ann.demo}: {ann.num_steps} steps, {ts[-1]:.2f} s ({ann.origin})"]
    for s in ann.skills:
        rows.append(f"  skill {s.index} {s.object:12s} steps [{s.start_step:4d}, {s.end_step:4d})  "
                    f"t [{ts[s.start_step]:6.2f}, {ts[s.end_step]:6.2f}) s")
    return "\n".join(rows)


def annotate_bag(path, task_name=None, rules_file=None, overrides=(), from_existing=False, check=False,
                 out=None, show=False) -> int:
    task = _task_of(path, task_name)
    arrays = read_demo_arrays(path)
    rules = rules_for(task.name, rules_file)
    if check:
        stored = read_annotation(path)
        if stored is None:
            raise AnnotationError(f"{path}: has no annotation to check", reason="ANNOTATION_NOT_FOUND")
        try:
            validate_annotation(stored, task, num_steps=len(arrays.timestamps))
        except AnnotationError as e:
            raise AnnotationError(f"{path}: {e.args[0]}", reason=e.reason) from e
        auto = propose(path, task, rules, arrays)
        same = [(s.start_step, s.end_step) for s in auto.skills] == [(s.start_step, s.end_step) for s in stored.skills]
        print(f"{path}: annotation valid ({stored.origin}); auto-annotation "
              f"{'reproduces it' if same else 'differs: ' + str([(s.start_step, s.end_step) for s in auto.skills])}")
        return 0
    if from_existing:
        ann = read_annotation(path)
        if ann is None:
            raise AnnotationError(f"{path}: --from-existing but the bag has no annotation",
                                  reason="ANNOTATION_NOT_FOUND")
    else:
        ann = propose(path, task, rules, arrays)
    if overrides:
        try:
            ann = apply_overrides(ann, [parse_override(o) for o in overrides], step_times(len(arrays.timestamps)),
                                  task)
        except AnnotationError as e:
            raise AnnotationError(f"{path}: {e.args[0]}", reason=e.reason) from e
    try:
        validate_annotation(ann, task, num_steps=len(arrays.timestamps))
    except AnnotationError as e:
        raise AnnotationError(f"{path}: {e.args[0]}", reason=e.reason) from e
    target = Path(out) if out else annotation_path(path)
    save_annotation(str(target), ann)
    print(_summary(ann) + f"\n  -> {target}")
    if show:
        print(dumps_annotation(ann))
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="skillgen annotate", description=__doc__.split("\n\n")[0])
    p.add_argument("bags", nargs="+", help="bag directories, .mcap files, or folders of bags")
    p.add_argument("--task", help="task name (default: the bag's scene record)")
    p.add_argument("--rules", help="YAML annotation rules (default: the built-in rules of the task)")
    p.add_argument("--override", action="append", default=[], metavar="SKILL.EDGE=STEP|SECONDSs",
                   help="move a skill boundary, e.g. 1.start=120 or 0.end=4.25s: seconds of the demo's control "
                        "time from its first step (step / 20 Hz); outside the demo is an error (repeatable)")
    p.add_argument("--from-existing", action="store_true", help="start from the stored annotation")
    p.add_argument("--check", action="store_true", help="only validate the stored annotation")
    p.add_argument("--out", help="write here instead of <bag>/annotations.yaml (one bag only)")
    p.add_argument("--print", dest="show", action="store_true", help="also print the annotation document")
    a = p.parse_args(argv)
    bags = expand_bag_paths(a.bags)
    if a.out and len(bags) != 1:
        raise AnnotationError("--out needs exactly one bag", reason="BAD_ARGUMENTS")
    failed = 0
    for b in bags:
        try:
            annotate_bag(b, a.task, a.rules, a.override, a.from_existing, a.check, a.out, a.show)
        except SkillGenError as e:
            print(str(e), file=sys.stderr)
            failed += 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

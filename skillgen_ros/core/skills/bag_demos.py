"""Source bags -> typed source demos: core/bag's reader + an annotation -> DemoArrays -> SourceDemo.

Pure glue, no rclpy: messages are decoded from the CDR bytes with the ros2msg schema stored in
the bag itself (mcap-ros2-support's dynamic decoder), so a bag is readable on any machine.

A control step is one `osc_target` message (the 20 Hz command stream); the observation of step
k (EE pose, gripper, joints, object poses) is the latest message of each stream at or before
that command (sample-and-hold), i.e. the state the command was computed from.
The scene (task, variant, seed) is the MCAP metadata record `skillgen_scene` (or a sidecar
`scene.yaml`); the annotation is the sidecar `annotations.yaml` or the record
`skillgen_annotations` (key `yaml`). Every error names the bag and the problem.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from ..bag.info import SIDECAR_ANNOTATIONS
from ..bag.reader import BagReader, schema_decoder
from ..bag.writer import ANNOTATIONS_RECORD
from ..errors import AnnotationError, BagError, SkillGenError
from ..robot import ARM_JOINTS
from .annotation import Annotation, load_annotation, loads_annotation
from .protocols import TaskLike, known_object_ids
from .segment import SourceDemo
from .source_demos import DemoArrays, sample_and_hold, source_demo_from_arrays

SCENE_RECORD = "skillgen_scene"
SIDECAR_SCENE = "scene.yaml"
# relative topic name -> the type the loader expects
SOURCE_TOPICS = {
    "joint_states": "sensor_msgs/msg/JointState",
    "ee_pose": "geometry_msgs/msg/PoseStamped",
    "gripper_state": "skillgen_interfaces/msg/GripperState",
    "osc_target": "skillgen_interfaces/msg/OscTarget",
    "sim/ground_truth/object_poses": "skillgen_interfaces/msg/ObjectPoseArray",
    "perception/object_poses": "skillgen_interfaces/msg/ObjectPoseArray",
    "object_joint_states": "sensor_msgs/msg/JointState",  # articulated objects' joints (a lid), optional
}
REQUIRED_TOPICS = ("ee_pose", "osc_target")
# Where a demo's object poses come from, in order of preference: what perception estimated during a
# (real-robot) recording, else the sim's ground truth (the scripted demonstrator's bags). One is required.
OBJECT_POSE_TOPICS = ("perception/object_poses", "sim/ground_truth/object_poses")


@dataclass(frozen=True)
class SceneInfo:
    """How to reset the sim to a demo's initial scene."""

    task: str
    variant: str = "D0"
    seed: int | None = None
    demo: str = ""


def _norm_type(t: str) -> str:
    parts = t.split("/")
    return f"{parts[0]}/msg/{parts[1]}" if len(parts) == 2 else t


@functools.lru_cache(maxsize=32)
def _decoder(schema_name: str, schema_text: str):
    return schema_decoder(schema_name, schema_text)


def open_bag(path) -> BagReader:
    """Open a source bag; a truncated or unreadable bag is an error here (a demo must be whole)."""
    try:
        reader = BagReader(path)
    except BagError as e:
        raise BagError(f"{path}: {e.args[0]}", e.reason) from e
    if reader.truncated:
        raise BagError(f"{path}: bag is truncated (a file has no valid footer; the recording was cut "
                       f"off); re-record or re-make this demo", "BAG_TRUNCATED")
    return reader


def find_topics(reader: BagReader, required=REQUIRED_TOPICS) -> dict[str, str]:
    """Relative topic -> its name in the bag (any namespace); checks required topics and types."""
    found = {}
    for rel, want in SOURCE_TOPICS.items():
        names = [n for n in reader.topics if n == rel or n == "/" + rel or n.endswith("/" + rel)]
        if not names:
            if rel in required:
                raise BagError(f"{reader.path}: required topic '{rel}' ({want}) is missing; the bag has "
                               f"{sorted(reader.topics)}", "MISSING_TOPIC")
            continue
        name = sorted(names, key=len)[0]
        if not reader.topics[name].schema_text:
            raise BagError(f"{reader.path}: topic '{name}' has no schema (its channel names none), so it cannot "
                           "be decoded; re-record it or run `skillgen bag reindex` on a copy that has one", "NO_SCHEMA")
        got = _norm_type(reader.topics[name].type)
        if got != want:
            raise BagError(f"{reader.path}: topic '{name}' has type {got}, expected {want}", "WRONG_TYPE")
        found[rel] = name
    return found


def _decode_all(reader: BagReader, topic: str) -> list[tuple[float, object]]:
    t = reader.topics[topic]
    if not t.schema_text:
        raise BagError(f"{reader.path}: topic '{topic}' has no schema to decode it with", "NO_SCHEMA")
    out = []
    try:
        dec = _decoder(t.type, t.schema_text)
        for m in reader.messages([topic]):
            out.append((m.log_time_ns * 1e-9, dec(m.data)))
    except BagError as e:
        raise BagError(f"{reader.path}: {e.args[0]}", e.reason) from e
    except Exception as e:  # noqa: BLE001 - CDR decoder raises plain errors on garbage bytes
        raise BagError(f"{reader.path}: cannot decode a '{topic}' message: {type(e).__name__}: {e}",
                       "CORRUPT_MESSAGE") from e
    return out


def _pose7(p) -> list[float]:
    return [p.position.x, p.position.y, p.position.z, p.orientation.x, p.orientation.y, p.orientation.z,
            p.orientation.w]


def read_scene(reader: BagReader) -> SceneInfo | None:
    """The demo's scene from the `skillgen_scene` record or the scene.yaml sidecar; None if absent."""
    rec = reader.metadata_records.get(SCENE_RECORD)
    if rec is None and reader.path.is_dir() and (reader.path / SIDECAR_SCENE).is_file():
        try:
            rec = yaml.safe_load((reader.path / SIDECAR_SCENE).read_text()) or {}
        except yaml.YAMLError as e:
            raise BagError(f"{reader.path / SIDECAR_SCENE}: not valid YAML: {e}", "BAD_SCENE") from e
    if rec is None:
        return None
    try:
        seed = rec.get("seed")
        return SceneInfo(str(rec["task"]), str(rec.get("variant", "D0")),
                         None if seed in (None, "", "None") else int(seed), str(rec.get("demo", "")))
    except (KeyError, ValueError, TypeError) as e:
        raise BagError(f"{reader.path}: scene record {rec!r} is malformed ({e})", "BAD_SCENE") from e


def demo_name(path) -> str:
    p = Path(path)
    return p.stem if p.suffix == ".mcap" else p.name


def read_demo_arrays(path, reader: BagReader | None = None) -> DemoArrays:
    """Decode a source bag into per-step arrays (see the module docstring for what a step is)."""
    reader = reader or open_bag(path)
    topics = find_topics(reader)
    src = str(path)
    cmds = _decode_all(reader, topics["osc_target"])
    if len(cmds) < 2:
        raise BagError(f"{src}: only {len(cmds)} osc_target messages; not a demo", "EMPTY_DEMO")
    t_cmd = np.array([t for t, _ in cmds])
    action = np.array([_pose7(m.pose) for _, m in cmds])
    grip = np.array([m.gripper for _, m in cmds], float)

    ee_msgs = _decode_all(reader, topics["ee_pose"])
    if not ee_msgs:
        raise BagError(f"{src}: topic 'ee_pose' has no messages", "MISSING_TOPIC")
    ee = sample_and_hold(t_cmd, [t for t, _ in ee_msgs], np.array([_pose7(m.pose) for _, m in ee_msgs]))

    obj_t: dict[str, list[float]] = {}
    obj_p: dict[str, list[list[float]]] = {}
    for pose_topic in (t for t in OBJECT_POSE_TOPICS if t in topics):
        for t, m in _decode_all(reader, topics[pose_topic]):
            for o in m.objects:
                obj_t.setdefault(o.id, []).append(t)
                obj_p.setdefault(o.id, []).append(_pose7(o.pose))
        if obj_t:
            break
    if not obj_t:
        raise BagError(f"{src}: no object poses: record one of {list(OBJECT_POSE_TOPICS)} with messages; "
                       f"the bag has {sorted(reader.topics)}", "MISSING_TOPIC")
    objs = {k: sample_and_hold(t_cmd, obj_t[k], np.array(obj_p[k])) for k in obj_t}

    joints = None
    if "joint_states" in topics:
        js = _decode_all(reader, topics["joint_states"])
        rows, times = [], []
        for t, m in js:
            idx = {n: i for i, n in enumerate(m.name)}
            if all(j in idx for j in ARM_JOINTS):
                rows.append([m.position[idx[j]] for j in ARM_JOINTS])
                times.append(t)
        if rows:
            joints = sample_and_hold(t_cmd, times, np.array(rows))
    scene = read_scene(reader)
    return DemoArrays(object_joints=_object_joints(reader, topics, t_cmd), 
        name=demo_name(path), source=src, timestamps=t_cmd - t_cmd[0],
        ee_positions=ee[:, :3], ee_quaternions=ee[:, 3:], gripper=grip,
        object_positions={k: v[:, :3] for k, v in objs.items()},
        object_quaternions={k: v[:, 3:] for k, v in objs.items()},
        action_positions=action[:, :3], action_quaternions=action[:, 3:], joint_positions=joints,
        variant=scene.variant if scene else "D0", scene_seed=scene.seed if scene else None,
        extra={"scene": scene})


def _object_joints(reader: BagReader, topics: dict, t_cmd: np.ndarray) -> dict[str, np.ndarray]:
    """"<id>/<joint>" -> (N,) from object_joint_states, sample-and-hold per name; {} without the topic."""
    times: dict[str, list[float]] = {}
    vals: dict[str, list[float]] = {}
    for t, m in (_decode_all(reader, topics["object_joint_states"]) if "object_joint_states" in topics else ()):
        for n, v in zip(m.name, m.position):
            times.setdefault(n, []).append(t)
            vals.setdefault(n, []).append(v)
    return {n: sample_and_hold(t_cmd, times[n], np.array(vals[n])) for n in times}


def read_annotation(path, reader: BagReader | None = None) -> Annotation | None:
    """The bag's annotation: sidecar annotations.yaml first, then the in-bag record; None if neither."""
    p = Path(path)
    side = p / SIDECAR_ANNOTATIONS if p.is_dir() else p.with_name(p.stem + "." + SIDECAR_ANNOTATIONS)
    if side.is_file():
        return load_annotation(str(side))
    reader = reader or open_bag(path)
    rec = reader.metadata_records.get(ANNOTATIONS_RECORD)
    if rec is not None:
        if "yaml" not in rec:
            raise AnnotationError(f"{path}: record '{ANNOTATIONS_RECORD}' lacks its 'yaml' field")
        return loads_annotation(rec["yaml"], f"{path} (record {ANNOTATIONS_RECORD})")
    return None


def annotation_path(path) -> Path:
    """Where `skillgen annotate` writes a bag's sidecar annotation."""
    p = Path(path)
    return p / SIDECAR_ANNOTATIONS if p.is_dir() else p.with_name(p.stem + "." + SIDECAR_ANNOTATIONS)


def load_source_demo(path, task: TaskLike, annotation: Annotation | str | None = None) -> SourceDemo:
    """Bag (+ its annotation, or the one given / the file named) -> validated SourceDemo."""
    reader = open_bag(path)
    scene = read_scene(reader)
    if scene is not None and scene.task != task.name:
        raise BagError(f"{path}: bag was recorded for task {scene.task!r}, not {task.name!r}", "WRONG_TASK")
    arrays = read_demo_arrays(path, reader)
    unknown = sorted(set(arrays.object_positions) - known_object_ids(task))
    if unknown:
        raise BagError(f"{path}: recorded objects {unknown} are not objects of task {task.name!r} "
                       f"(known: {sorted(known_object_ids(task))})", "UNKNOWN_OBJECT")
    if isinstance(annotation, (str, Path)):
        annotation = load_annotation(str(annotation))
    elif annotation is None:
        annotation = read_annotation(path, reader)
    try:
        return source_demo_from_arrays(arrays, annotation, task)
    except SkillGenError as e:
        msg = e.args[0]
        raise type(e)(msg if str(path) in msg else f"{path}: {msg}", e.reason) from e


def load_source_demos(paths, task: TaskLike) -> list[SourceDemo]:
    """Every bag in `paths` (bag dirs, .mcap files, or a folder of bag dirs) as source demos."""
    return [load_source_demo(p, task) for p in expand_bag_paths(paths)]


def is_bag(p: Path) -> bool:
    return (p.is_file() and p.suffix == ".mcap") or (p.is_dir() and (
        (p / "metadata.yaml").is_file() or any(p.glob("*.mcap"))))


def expand_bag_paths(paths) -> list[Path]:
    """Bag paths from a mix of bags and folders holding bags (sorted, one level deep)."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    out = []
    for p in map(Path, paths):
        if is_bag(p):
            out.append(p)
        elif p.is_dir():
            out += sorted(c for c in p.iterdir() if is_bag(c))
        else:
            raise BagError(f"{p}: no such bag or folder of bags", "BAG_NOT_FOUND")
    return out


class SourceDemoCache:
    """Source demos by (bag files, task), parsed once and reloaded when a bag's files change.

    A node serves many goals over the same demos (a distributed worker's graph gets one goal per
    index range); parsing Square's 10 bags takes about 0.7 s each time. The key is every file of
    every bag with its size and mtime, so an edited annotation or a re-recorded bag is read again.
    SourceDemo is frozen and the run loop only reads it, so the cached lists are shared as is.
    """

    def __init__(self, size: int = 4):
        self.size = size
        self._entries: dict[tuple, list[SourceDemo]] = {}

    @staticmethod
    def _key(paths: list[Path], task: TaskLike) -> tuple:
        files = []
        for p in paths:
            for f in sorted(p.iterdir()) if p.is_dir() else [p]:
                st = f.stat()
                files.append((str(f.resolve()), st.st_size, st.st_mtime_ns))
        return (task.name, tuple(files))

    def load(self, paths, task: TaskLike) -> list[SourceDemo]:
        """load_source_demos(paths, task), from the cache when nothing changed."""
        bags = expand_bag_paths(paths)
        key = self._key(bags, task)
        if key not in self._entries:
            demos = load_source_demos(bags, task)
            while len(self._entries) >= self.size:
                self._entries.pop(next(iter(self._entries)))  # the oldest entry
            self._entries[key] = demos
        return self._entries[key]

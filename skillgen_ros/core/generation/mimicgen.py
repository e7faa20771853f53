"""The MimicGen baseline, as NVlabs/mimicgen generates (Mandlekar et al., 2023).

Followed line by line (NVlabs/mimicgen as read: datagen/* at 71c5e6c, utils/file_utils.py at 08d0fb2,
scripts/generate_core_configs.py at 33fcab6, exps/templates/robosuite/*.json at 7004c1b / 14fc947):
- subtasks: `mimicgen/utils/file_utils.py` parse_source_dataset: subtask i ends one step after its
  termination signal first reads 1 (`end_ind + 1`) and the next starts there; the last ends with
  the demo. `mimicgen/datagen/data_generator.py` randomize_subtask_boundaries: each end but the
  last moves by an offset drawn uniformly from the config's subtask_term_offset_range (inclusive),
  per source demo, anew for every attempt.
- selection: data_generator.select_source_demo + `mimicgen/datagen/selection_strategy.py`
  (`nearest_neighbor_object`: pos + rot distance between the subtask object's pose now and at the
  start of the source subtask, one of the nn_k nearest uniformly; `random`), only for the first
  subtask unless select_src_per_subtask.
- transform: data_generator.generate + PoseUtils.transform_source_data_segment_using_object_pose:
  the whole segment's target poses T_W^{A_t'} = T_W^{O'} (T_W^{O_src})^-1 T_W^{A_t}; the first
  subtask's segment starts with the source robot's EE pose at its first step (src_eef_poses =
  eef_pose[0:1] + target poses); gripper actions get their first value prepended for every subtask
  and are then read by waypoint index (so a later subtask's gripper lags its poses by one step, as
  in the reference).
- interpolation: `mimicgen/datagen/waypoint.py` WaypointTrajectory.merge /
  add_waypoint_sequence_for_target_pose and PoseUtils.interpolate_poses: from the current EE pose
  (first subtask) or the previous subtask's last target (interpolate_from_last_target_pose),
  num_interpolation_steps poses strictly between, then the segment's first pose, then
  num_fixed_steps holds; no noise on these (apply_noise_during_interpolation false) except the
  segment's first pose, which keeps its noise.
- execution: waypoint.WaypointTrajectory.execute: a normalized delta-pose action from the current
  EE pose, plus N(0,1) * action_noise, clipped to [-1, 1]; success is `task` success at any step
  (`success[k] = success[k] or cur_success_metrics[k]`; generate: `generated_success or ...`).
- settings: `mimicgen/scripts/generate_core_configs.py` and `mimicgen/exps/templates/robosuite/
  {square,threading,nut_assembly,pick_place}.json`: action noise 0.05, 5 interpolation steps,
  0 fixed steps; see MIMICGEN_SPECS.

Our source demos carry skill annotations, not MimicGen's per-step signals. Subtask i is skill i's
object-centric subtask (its object is MimicGen's object_ref); its signal is the last step of skill
i's annotated segment at which the gripper command changed to the state it ends the skill in: the
close of a grasp, the release of a place, as the annotation rules key on them. robosuite's grasp
signal rises when both fingers touch, a few periods after that command. A skill with several
gripper events ends at its last: Coffee Prep's place-mug-and-open-lid releases the mug, then
pinches and releases the lid (MimicGen's `mug_place` signal: the mug placed and the lid past 2.08
rad, i.e. opened), and its open-drawer grasps the bar, pulls and lets go (`drawer_open`: the slide
past -0.19 m, about 15 steps before our demos let go; the first event, the grasp of the bar, would
leave the pull to the pod's subtask, in the pod's frame).
The source object pose at a subtask's start is the skill segment's `object_pose` (observed
before the skill): the skill's object does not move in a source demo between its subtask's start and
its skill's (Coffee Prep's pod rides out with the drawer before its subtask starts, and stays within 2 mm after,
in every shipped demo).
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, Sequence

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..errors import InvalidInputError
from ..skills.protocols import TaskLike
from ..skills.segment import SourceDemo
from ..skills.transform import matrix_to_array
from .episode import StepLabel
from .selection import make_strategy

if TYPE_CHECKING:
    from .attempt import _Attempt


@dataclass(frozen=True)
class MimicGenSpec:
    """One task's MimicGen settings (a config's task_spec, the same for every subtask here)."""

    offset_range: tuple[int, int] = (10, 20)  # subtask_term_offset_range of every subtask but the last
    selection: str = "random"  # "nearest_neighbor_object" or "random"
    nn_k: int = 3
    select_src_per_subtask: bool = False
    num_interpolation_steps: int = 5
    num_fixed_steps: int = 0
    action_noise: float = 0.05
    interpolate_from_last_target_pose: bool = True

    def __post_init__(self):
        lo, hi = self.offset_range
        if lo < 0 or hi < lo or self.nn_k < 1 or self.selection not in ("nearest_neighbor_object", "random"):
            raise InvalidInputError(f"bad MimicGen spec {self}", reason="INVALID_PARAMETER")


# generate_core_configs.py make_generators(): square and nut_assembly use nearest_neighbor_object
# with nn_k=3 and offsets [10, 20]; threading random with [5, 10]; pick_place (robosuite's four-object
# task, ours has one object) nearest_neighbor_object nn_k=3, [10, 20], select_src_per_subtask=True; its
# place subtasks have no object_ref (robosuite's bins are fixed), ours moves with the bin (D2 moves it).
MIMICGEN_SPECS: dict[str, MimicGenSpec] = {
    "Square": MimicGenSpec((10, 20), "nearest_neighbor_object", 3),
    "NutAssembly": MimicGenSpec((10, 20), "nearest_neighbor_object", 3),
    "Threading": MimicGenSpec((5, 10), "random"),
    "PickPlace": MimicGenSpec((10, 20), "nearest_neighbor_object", 3, select_src_per_subtask=True),
    # three_piece_assembly: random, [5, 10] for each of its 3 subtask ends
    "ThreePieceAssembly": MimicGenSpec((5, 10), "random"),
    # coffee (generate_core_configs.py make_generators): random, [5, 10] for its grasp subtask, no source per subtask
    "Coffee": MimicGenSpec((5, 10), "random"),
    # coffee_preparation: random, [5, 10] for each of its 4 subtask ends, no source per subtask
    "CoffeePreparation": MimicGenSpec((5, 10), "random"),
}
DEFAULT_SPEC = MimicGenSpec()  # a task MimicGen has no config for: its template defaults


def spec_for(task: str) -> MimicGenSpec:
    return MIMICGEN_SPECS.get(task, DEFAULT_SPEC)


def spec_record(task: str) -> dict:
    """The settings a dataset's env_args records for a MimicGen run."""
    d = asdict(spec_for(task))
    d["offset_range"] = list(d["offset_range"])
    return d


def subtask_signals(demo: SourceDemo, task: TaskLike) -> list[int]:
    """Per subtask but the last: the first step its termination signal reads 1 (see the docstring)."""
    out = []
    for sk in sorted(task.skills, key=lambda s: s.index)[:-1]:
        seg = demo.skill(sk.index)
        closed = np.asarray(demo.gripper[seg.start_step:seg.end_step], float) > 0
        events = np.flatnonzero(closed[1:] != closed[:-1]) + 1  # steps whose command differs from the one before
        ending = events[closed[events] == closed[-1]] if closed.size else events
        if ending.size:
            out.append(int(seg.start_step + ending[-1]))
        elif closed.size and closed[0] != (sk.mode == "transfer"):  # changed at the segment's first step
            out.append(int(seg.start_step))
        else:
            out.append(int(seg.end_step - 1))
    return out


def subtask_bounds(demo: SourceDemo, task: TaskLike, offsets: Sequence[int]) -> np.ndarray:
    """(S, 2) half-open [start, end) steps of each subtask, with `offsets` added to each end but the last."""
    signals = subtask_signals(demo, task)
    if len(offsets) != len(signals):
        raise InvalidInputError(f"{len(offsets)} offsets for {len(signals)} subtask ends", reason="INVALID_PARAMETER")
    ends = [s + 1 + int(o) for s, o in zip(signals, offsets)] + [demo.num_steps]
    b = np.array([[0] + ends[:-1], ends]).T
    if (np.diff(b, axis=1) <= 0).any() or b[-1, 1] > demo.num_steps or (np.diff(b[:, 1]) <= 0).any():
        raise InvalidInputError(f"{demo.source}: demo {demo.name}: empty or unordered MimicGen subtasks {b.tolist()} "
                                f"(offsets {list(offsets)}, {demo.num_steps} steps)", reason="BAD_SUBTASKS")
    return b


def check_subtasks(demos: Sequence[SourceDemo], task: TaskLike) -> None:
    """parse_source_dataset's sanity check, before anything moves: no offset draw may leave a subtask
    empty (end_i + max offset < end_{i+1} + min offset; the last ends with the demo)."""
    lo, hi = spec_for(task.name).offset_range
    n = len(task.skills)
    for d in demos:
        subtask_bounds(d, task, [hi] * (n - 1))
        if n > 2:
            ends = [s + 1 for s in subtask_signals(d, task)]
            if any(e0 + hi >= e1 + lo for e0, e1 in zip(ends[:-1], ends[1:])):
                raise InvalidInputError(f"{d.source}: demo {d.name}: MimicGen subtask ends {ends} are closer than "
                                        f"the offset range {lo}-{hi} allows", reason="BAD_SUBTASKS")


def draw_offsets(n_demos: int, n_subtasks: int, spec: MimicGenSpec, rng: np.random.Generator) -> np.ndarray:
    """(N, S-1) end offsets, drawn subtask by subtask for all demos as randomize_subtask_boundaries does."""
    lo, hi = spec.offset_range
    cols = [rng.integers(lo, hi + 1, size=n_demos) for _ in range(n_subtasks - 1)]
    return np.stack(cols, axis=1) if cols else np.zeros((n_demos, 0), int)


def interpolate(T1: np.ndarray, T2: np.ndarray, num_steps: int) -> np.ndarray:
    """PoseUtils.interpolate_poses: num_steps + 2 poses from T1 to T2 (both included), positions
    evenly spaced; rotations along the relative axis-angle, all T2's when it is under 0.05 rad."""
    T1, T2 = np.asarray(T1, float), np.asarray(T2, float)
    if num_steps == 0:
        return np.stack([T1, T2])
    n = num_steps + 1
    s = np.arange(n) / n
    out = np.tile(np.eye(4), (n + 1, 1, 1))
    out[:n, :3, 3] = T1[:3, 3] + s[:, None] * (T2[:3, 3] - T1[:3, 3])
    out[n] = T2
    if Rotation.from_matrix(T2[:3, :3] @ T1[:3, :3].T).magnitude() < 0.05:
        out[:n, :3, :3] = T2[:3, :3]
    else:
        out[:n, :3, :3] = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([T1[:3, :3], T2[:3, :3]])))(s).as_matrix()
    return out


@dataclass(frozen=True)
class Waypoints:
    """What one subtask executes: targets, gripper, noise scale and whether a step interpolates."""

    targets: np.ndarray  # (K,4,4)
    gripper: np.ndarray  # (K,)
    noise: np.ndarray  # (K,)
    interpolating: np.ndarray  # (K,) bool


def subtask_waypoints(demo: SourceDemo, bounds: np.ndarray, T_W_O_src: np.ndarray, T_W_O_new: np.ndarray,
                      start_pose: np.ndarray, first: bool, spec: MimicGenSpec) -> Waypoints:
    """The merged interpolation + transformed segment of one subtask, as data_generator.generate builds it."""
    a, b = int(bounds[0]), int(bounds[1])
    poses = np.asarray(demo.action_poses[a:b], float)
    if first:
        poses = np.concatenate([np.asarray(demo.ee_poses[a:a + 1], float), poses])
    g = np.asarray(demo.gripper[a:b], float)
    grip = np.concatenate([g[:1], g])[:len(poses)]
    moved = np.asarray(T_W_O_new, float) @ np.linalg.inv(np.asarray(T_W_O_src, float)) @ poses
    noise = np.full(len(moved), spec.action_noise)
    n_i, n_f = spec.num_interpolation_steps, spec.num_fixed_steps
    if n_i <= 0 and n_f <= 0:
        return Waypoints(moved, grip, noise, np.zeros(len(moved), bool))
    lead = []
    if n_i > 0:
        lead.append(interpolate(start_pose, moved[0], n_i)[1:])
    if n_f > 0:
        lead.append(np.repeat(moved[:1], n_f if n_i > 0 else n_f + 1, axis=0))
    lead = np.concatenate(lead)
    lead_noise = np.zeros(len(lead))
    lead_noise[-1] = noise[0]  # merge(): "preserve noise from first element of other trajectory"
    return Waypoints(np.concatenate([lead, moved[1:]]), np.concatenate([np.full(len(lead), grip[0]), grip[1:]]),
                     np.concatenate([lead_noise, noise[1:]]), np.concatenate([np.ones(len(lead), bool),
                                                                              np.zeros(len(moved) - 1, bool)]))


def run_mimicgen(at: "_Attempt") -> None:
    """One MimicGen attempt (data_generator.generate) inside an _Attempt: reset, then per subtask
    estimate its object's pose, select (first subtask, or each), transform, interpolate, execute."""
    spec = replace(spec_for(at.task.name), action_noise=at.cfg.action_noise,  # the run's settings
                   num_interpolation_steps=at.cfg.interpolation_steps, num_fixed_steps=at.cfg.fixed_steps)
    skills = sorted(at.task.skills, key=lambda s: s.index)
    offsets = draw_offsets(len(at.demos), len(skills), spec, at.rng_subtasks)
    at.reset(at.cfg.variant, at.scene_seed)
    strategy = make_strategy("nearest_neighbor" if spec.selection == "nearest_neighbor_object" else "random_per_skill",
                             **({"nn_k": spec.nn_k} if spec.selection == "nearest_neighbor_object" else {}))
    last_target, j = None, None
    for i, skill in enumerate(skills):
        T_W_O = at.estimate(skill)
        if j is None or spec.select_src_per_subtask:
            j = strategy.select(at.demos, skill.index, T_W_O, None, at.rng_select)
        at.chosen.append(j)
        bounds = subtask_bounds(at.demos[j], at.task, offsets[j])[i]
        use_last = spec.interpolate_from_last_target_pose and last_target is not None
        start = last_target if use_last else at.obs.ee_matrix()
        w = subtask_waypoints(at.demos[j], bounds, at.demos[j].skill(skill.index).object_pose, T_W_O, start,
                              i == 0, spec)
        goal7 = matrix_to_array(w.targets[int(w.interpolating.sum()) - 1 if w.interpolating.any() else 0])
        for T, g, sigma, interp in zip(w.targets, w.gripper, w.noise, w.interpolating):
            t = time.perf_counter()
            at._step(T, float(g), float(sigma), StepLabel(bool(interp), skill.index, j, goal7))
            at._timed("motion" if interp else "skill", t)
            t = time.perf_counter()
            if not at.success_seen and at.env.task_success():
                at.success_seen = True
            at._timed("success", t)
        last_target = w.targets[-1]

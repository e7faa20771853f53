"""bench/datagen/attempt_tally.py: what bench/datagen/diagnose.py measures in each attempt, and its tally.

Each measure reads one finished attempt's recorded episode (true object poses, joint values, labels):
how far a failed Coffee / Coffee Prep / Three Piece attempt got, how far a carried object slid before it was lifted,
how far a held object slipped in the hand,
which joints met their limits in a skill. `Tally` sums them over a cell.
"""
from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import dataclass, field

import numpy as np

LIFTED, LID_OPENED = 0.05, 1.3   # m above its start; rad (the demos swing the lid to 1.55-1.8 rad)
PIECE_LIFTED = 0.02  # m: Three Piece's source demos carry piece_1 22-25 cm up, piece_2 17-19 cm
NEAR_BASE = 0.05  # m: piece 1 ending this near the base's centre missed the hole (on its rim), not the base
PIECE_SEATED = 0.01  # m: piece 1 this close to its starting height is down (in the base's hole, on the table)


def coffee_prep_stage(obs: dict) -> str:
    """How far a failed Coffee Prep attempt got, from its recorded true object poses and joint values."""
    from skillgen_ros.core.tasks import coffee as C
    from skillgen_ros.core.tasks import coffee_prep as CP

    mug, pod = np.asarray(obs["mug_pose"])[:, 2], np.asarray(obs["coffee_pod_pose"])[:, 2]
    lid, slide = np.asarray(obs["coffee_machine_joints"])[:, 0], np.asarray(obs["drawer_joints"])[:, 0]
    if mug.max() - mug[0] < LIFTED:
        return "1 mug not lifted"
    if lid.max() < LID_OPENED:
        return "2 lid never opened"
    if slide.min() > CP.DRAWER_OPEN:
        return "3 drawer not opened"
    if pod.max() - pod[0] < LIFTED:
        return "4 pod not lifted"
    if lid[-1] > C.LID_CLOSED_TOLERANCE:
        return "5 pod carried, lid not closed"
    return "6 lid closed, pod or mug not in place"


def coffee_stage(obs: dict) -> str:
    """How far a failed Coffee attempt got, at its last step: which part of coffee.py's `_check_pod` /
    `_check_lid` fails, with the pod's x-y miss from the holder centre (allowed: 5.2 mm) in 5 mm bins."""
    from scipy.spatial.transform import Rotation as R

    from skillgen_ros.core.tasks import coffee as C

    pod, machine = np.asarray(obs["coffee_pod_pose"], float), np.asarray(obs["coffee_machine_pose"], float)
    lid = np.asarray(obs["coffee_machine_joints"], float)[:, 0]
    if pod[:, 2].max() - pod[0, 2] < LIFTED:
        return "1 pod not lifted"
    holder = R.from_quat(machine[-1, 3:]).apply(C.coffee_machine().keypoint("pod_holder")) + machine[-1, :3]
    miss = C.pod_miss(holder, pod[-1])
    if miss > C.POD_MISS_ALLOWED:
        return f"2 pod beside the holder, x-y miss {5 * int(miss * 200)}-{5 * int(miss * 200) + 5} mm"
    if C.pod_below_holder(holder, pod[-1]):
        return "3 pod below the holder's bottom"
    if lid[-1] >= C.LID_CLOSED_TOLERANCE:
        deg = 15 * int(np.degrees(lid[-1]) // 15)
        return f"4 pod in the holder, lid open {deg}-{deg + 15} deg at the end"
    return "5 lid closed, pod on the holder's rim (top above the lid's underside)"


def three_piece_stage(obs: dict) -> str:
    """How far a failed Three Piece Assembly attempt got, read against MimicGen's three_piece_assembly.py
    checks (x-y within 2 cm, piece 2's centre within 2 cm of base z + 8 cm): where piece 1 was lost, or how
    piece 2 missed piece 1 at the last step (x-y miss in 1 cm bins)."""
    from skillgen_ros.core.tasks import assembly as A

    base, p1, p2 = (np.asarray(obs[f"{k}_pose"], float)[:, :3] for k in ("base", "piece_1", "piece_2"))
    # in the base's hole, piece 1 rests on the table as it started (carried over the base, it is higher)
    on_base = (np.linalg.norm(p1[:, :2] - base[:, :2], axis=1) < A.XY_THRESH) & (p1[:, 2] < p1[0, 2] + PIECE_SEATED)
    if p1[:, 2].max() - p1[0, 2] < PIECE_LIFTED:
        return "1 piece_1 never lifted"
    if not on_base.any():
        near = np.linalg.norm(p1[-1, :2] - base[-1, :2]) < NEAR_BASE
        return f"2 piece_1 lifted, never seated; it ends {'within' if near else 'over'} 5 cm of the base's centre"
    if not on_base[-1]:
        return "3 piece_1 on the base, knocked off later"
    if p2[:, 2].max() - p2[0, 2] < PIECE_LIFTED:
        return "4 piece_2 never lifted"
    miss = float(np.linalg.norm(p2[-1, :2] - p1[-1, :2]))
    if miss >= A.XY_THRESH:
        return f"5 piece_2 beside piece_1, x-y miss {int(miss * 100)}-{int(miss * 100) + 1} cm"
    if abs(p2[-1, 2] - (base[-1, 2] + A.Z_CORRECT_ABOVE_BASE)) >= A.Z_THRESH:
        return "6 piece_2 over piece_1, not down (z off by >= 2 cm)"
    return "7 both placed, a piece still held"


STAGES = {"CoffeePreparation": coffee_prep_stage, "Coffee": coffee_stage,   # tasks whose failures --stages can place
          "ThreePieceAssembly": three_piece_stage}
DRAGGED = 0.02  # m: an object that slid this far across the table before it was first lifted was dragged


def drags(ep, spec) -> dict[str, float]:
    """Per object that a transit skill grasps and a transfer skill then carries: how far it slid in x-y from
    its grasp skill's first step until it first rose 1 cm above where it was then (to the attempt's end if
    it never rose). A carried object slides ~0; one pulled along the table by the next segment, cm."""
    carried = {getattr(sk, "attached_object", None) for sk in spec.skills if sk.mode == "transfer"}
    skill_of = np.asarray(ep.labels["skill_index"])
    out = {}
    for sk in spec.skills:
        key = f"{sk.object_id}_pose"
        steps = np.flatnonzero(skill_of == sk.index)
        if sk.mode != "transit" or sk.object_id not in carried or key not in ep.obs or not steps.size:
            continue
        p = np.asarray(ep.obs[key], float)[steps[0]:, :3]
        risen = np.flatnonzero(p[:, 2] > p[0, 2] + 0.01)
        before = p[: risen[0] + 1] if risen.size else p
        out[sk.object_id] = float(np.linalg.norm(before[:, :2] - p[0, :2], axis=1).max())
    return out


SLIPPED = 0.01  # m: a held object this far from where it sat in the hand after the grasp slipped in it
GRASP_SETTLE = 3  # control steps after the close: the fingers stop on the object by the 3rd


def slips(ep, spec) -> dict[str, float]:
    """Per object that a transfer skill carries: how far it moved in the hand (the EE frame) while held, from
    GRASP_SETTLE steps after its grasp skill's close until the hand next opens (or the attempt ends)."""
    from scipy.spatial.transform import Rotation

    carried = {getattr(sk, "attached_object", None) for sk in spec.skills if sk.mode == "transfer"}
    skill_of, grip = np.asarray(ep.labels["skill_index"]), np.asarray(ep.actions_abs, float)[:, 7] > 0
    ee_p = np.asarray(ep.obs["robot0_eef_pos"], float)
    ee_r = Rotation.from_quat(np.asarray(ep.obs["robot0_eef_quat"], float))
    out = {}
    for sk in spec.skills:
        steps = np.flatnonzero((skill_of == sk.index) & grip)
        if sk.mode != "transit" or sk.object_id not in carried or not steps.size:
            continue
        a = steps[0] + GRASP_SETTLE
        opened = np.flatnonzero(~grip[a:])
        b = a + (opened[0] if opened.size else len(grip) - a)
        if b <= a:
            continue
        obj = np.asarray(ep.obs[f"{sk.object_id}_pose"], float)[a:b, :3]
        in_hand = ee_r[a:b].inv().apply(obj - ee_p[a:b])
        out[sk.object_id] = float(np.linalg.norm(in_hand - in_hand[0], axis=1).max())
    return out


AT_LIMIT = np.radians(1.0)  # a joint within this of its position limit is on it
JOINT_LIMITS: tuple | None = None  # (lower, upper) the sim enforces, when not core/robot.py's Q_LOWER / Q_UPPER


def joints_at_limit(ep) -> list[int]:
    """The arm joints (0-based, panda_joint1 = 0) that reached within 1 deg of a position limit during any
    skill's replay (mp_step == 0): a rigidly transformed skill whose wrist turn runs past panda_joint7's range
    leaves the hand short of its targets."""
    from skillgen_ros.core.robot import Q_LOWER, Q_UPPER

    lower, upper = JOINT_LIMITS or (Q_LOWER, Q_UPPER)
    q = np.asarray(ep.obs["robot0_joint_pos"], float)[np.asarray(ep.labels["mp_step"]) == 0]
    if not len(q):
        return []
    hit = (q <= lower + AT_LIMIT) | (q >= upper - AT_LIMIT)
    return [int(j) for j in np.flatnonzero(hit.any(axis=0))]


def _collect(measured: dict, per_object: dict, attempts: list, threshold: float, ok: int) -> None:
    """One attempt's per-object distances (drags / slips) into their lists, and [attempts, successes] over
    `threshold` (the attempt counts once, whichever object went past it)."""
    for k, v in measured.items():
        per_object[k].append(v)
    if any(v > threshold for v in measured.values()):
        attempts[0] += 1
        attempts[1] += ok


def _spread(per_object: dict) -> dict:
    return {k: {"median": float(np.median(v)), "p90": float(np.percentile(v, 90)), "n": len(v)}
            for k, v in per_object.items()}


@dataclass
class Tally:
    """What diagnose counts over a cell's attempts (one add() per attempt, summary() for the entry)."""

    task: str
    stages: bool
    by_demo: dict = field(default_factory=lambda: defaultdict(lambda: [0, 0]))  # last skill's demo -> [ok, n]
    reasons: Counter = field(default_factory=Counter)
    at_skill: Counter = field(default_factory=Counter)  # failure reason and the last skill whose initiation was planned
    reached: Counter = field(default_factory=Counter)
    look_rows: list = field(default_factory=list)  # (success, looks) per attempt
    touched: list = field(default_factory=lambda: [0, 0])  # attempts touching `touch`, and how many succeeded
    slides: dict = field(default_factory=lambda: defaultdict(list))  # object -> how far it slid, per attempt
    at_limit: dict = field(default_factory=lambda: defaultdict(lambda: [0, 0]))  # joint -> [attempts, successes]
    dragged: list = field(default_factory=lambda: [0, 0])  # attempts dragging an object, and how many succeeded
    in_hand: dict = field(default_factory=lambda: defaultdict(list))  # object -> how far it slipped in the hand
    slipped: list = field(default_factory=lambda: [0, 0])  # attempts in which a held object slipped, successes

    def add(self, r, spec, looks, touching) -> None:
        """One attempt's result `r`, with the looks and touch counter diagnose's wrappers recorded during it."""
        ok = int(r.success)
        self.look_rows.append((bool(r.success), list(looks) if looks is not None else []))
        if touching and touching[0] > 0:
            self.touched[0] += 1
            self.touched[1] += ok
        if r.episode is not None:
            _collect(drags(r.episode, spec), self.slides, self.dragged, DRAGGED, ok)
            _collect(slips(r.episode, spec), self.in_hand, self.slipped, SLIPPED, ok)
        for j in joints_at_limit(r.episode) if r.episode is not None else []:
            self.at_limit[f"panda_joint{j + 1}"][0] += 1
            self.at_limit[f"panda_joint{j + 1}"][1] += ok
        d = int(r.source_demos[-1]) if r.source_demos else -1
        self.by_demo[d][0] += ok
        self.by_demo[d][1] += 1
        if not r.success:
            self.reasons[f"{r.reason.value}: {r.message[:80]}"] += 1
            if r.initiation_candidates_used:
                self.at_skill[f"{r.reason.value} at skill {len(r.initiation_candidates_used) - 1}"] += 1
            if self.stages and r.reason.value == "TASK_FAILED":
                self.reached[STAGES[self.task](r.episode.obs)] += 1

    def summary(self) -> dict:
        """The entry's counts (diagnose adds the run's settings)."""
        n_ok = sum(v[0] for v in self.by_demo.values())
        out = {"successes": n_ok,
               "by_source_demo": {str(k): {"successes": v[0], "attempts": v[1]} for k, v in sorted(self.by_demo.items())},
               "failures": dict(self.reasons.most_common()), "failures_at_skill": dict(sorted(self.at_skill.items())),
               "drag_measure": "from the grasp skill's first step",  # entries without it measured from step 0
               "drag_m": _spread(self.slides),
               "attempts_dragging": self.dragged[0], "successes_dragging": self.dragged[1],
               "slip_in_hand_m": _spread(self.in_hand),
               "attempts_slipping": self.slipped[0], "successes_slipping": self.slipped[1],
               "joint_at_limit_in_a_skill": {k: {"attempts": v[0], "successes": v[1]}
                                             for k, v in sorted(self.at_limit.items())},
               "successful_indices": [i for i, (ok, _) in enumerate(self.look_rows) if ok]}
        if self.stages:
            out["task_failed_stages"] = dict(sorted(self.reached.items()))
        return out

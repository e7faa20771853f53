"""The scripted demonstrator: drives SimWorld's OSC interface the way a person would.

It exists ONLY to produce the shipped source demos (bags/) without a human at a keyboard; it is
not a policy, never used during generation, and knows privileged object poses. Each demo gets
its own `DemoStyle` (speed, tremor, pauses, approach direction, aim error) from the demo seed.

Plans are phase by phase and re-read the scene at each phase start, like a person looking
before moving: grasps are planned from the object's current pose, placements from the measured
grasp (the object pose in the hand right after lifting). Each step records the observation, then
the command sent (see record.DemoStep).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from ..geometry import Pose
from ..robot import ARM_JOINTS, TABLE_Z
from ..tasks import get_task
from ..tasks import scripted_coffee_prep
from ..tasks.scripted import MAX_EE_YAW, ScriptParams, Scripter
from .motion import DemoStyle, SmoothNoise, down_pose, ee_yaw, nearest_yaw, object_yaw, reach
from .record import DemoRollout, DemoStep

CONTROL_HZ = 20.0
NOMINAL = ScriptParams()  # the privileged solver's grasp / place geometry; the person varies around it
OPEN, CLOSED = -1.0, 1.0
# Three Piece Assembly: grasp this far below a piece's top (the middle of piece 2's 4 cm knob, the top of
# piece 1's ridge); carry at this height above the table (piece 2 hangs 14 cm below the hand over the 10 cm
# piece 1); release this far above the seat
PIECE_GRASP_DEPTH = 0.02
PIECE_TRAVEL = 0.30
PIECE_DROP = 0.008
# Coffee: grasp the pod at its "grasp" keypoint; let go once its bottom is this far into the holder (the finger
# pads still above the holder's rim: the pod slides the rest of the way down the cup); push the open lid shut
# from behind with the open hand at this height (machine frame z, 5.4 cm above the hinge), along machine +y
POD_RELEASE_IN = 0.025
LID_PUSH_Z, LID_PUSH_FROM, LID_PUSH_TO = 0.16, -0.03, 0.11


class _PersonAsEnv:
    """The world as scripted.Scripter drives it (scripted.py's env), every command recorded as this demo's step."""

    def __init__(self, demo: "ScriptedDemonstrator", world):
        self.demo, self.world, self.control_hz = demo, world, CONTROL_HZ

    def __getattr__(self, name):   # scene, ee_pose, object_poses, object_joints, task_success
        return getattr(self.world, name)

    def step(self, pose: Pose, gripper: float) -> None:
        self.demo._send(self.world, pose, gripper)


class ScriptedDemonstrator:
    """Runs one human-like demo of a task on a SimWorld; see the module docstring."""

    # Coffee: False (the shipped demos since 2026-12-06) pushes the lid at the pod grasp's yaw, 4 cm lower, where
    # the finger base meets the lid (the open fingers, across the push, would straddle it). True turns the hand to
    # the machine's yaw first, 90 deg from the grasp's (the earlier demos): SkillGen replays that turn rigidly and
    # in D2's turned machines it runs panda_joint7 onto its limit (bench/datagen/coffee_lid_push.py: D2 14/40
    # from the turning demos vs 26/40 without the turn).
    LID_PUSH_TURNS = False
    # After closing on an object the person lifts as soon as the fingers have stopped, as a teleoperator does: they
    # reach the object in 2 control periods and stop by the 3rd (widths 80 -> 43 -> 36 -> 35.5 mm), so the hand
    # holds GRASP_SETTLE_S[True] and rises its first PROMPT_RISE, the first cm 8-10 steps after the close. False: the
    # demos shipped until 2026-12-06, which held 0.6-0.78 s and eased the lift in (min-jerk), the first cm 23-28
    # steps after the close, past MimicGen's subtask ends (the grasp + 5-10 steps, 10-20 for Square and Nut
    # Assembly): its next subtask then began with the object on the table and dragged it there
    # (bench/datagen/grasp_hold.py; docs/source_demos.md).
    PROMPT_LIFT = True
    GRASP_SETTLE_S = {True: 0.15, False: 0.6}
    PROMPT_RISE = (0.03, 0.3)  # m, s
    COFFEE_PREP_GRASP_DWELL = {True: (3, 5), False: (10, 15)}  # control periods, the privileged script's dwell
    # After opening on a placed object: False (the shipped demos) holds 0.5-0.65 s and eases the retreat in
    # (min-jerk), the first cm 16-22 steps after the open, past MimicGen's ends of a place subtask (its signal +
    # 5-10 steps, 10-20 for Nut Assembly), so its next subtask begins with the open hand still down at the placed
    # object. True rises as soon as the fingers are off it (RELEASE_SETTLE_S, then PROMPT_RISE, then the rest of the
    # retreat; Coffee Prep's privileged script dwells 3-4 periods): the first cm 8-9 steps after the open. Not
    # shipped: on Three Piece D0 it stops MimicGen sweeping piece 1 off the base (12 -> 3 of 40 attempts) but
    # moves the failures on to piece 2 (8 -> 12 of 40 succeed), and the demonstrator fails Nut Assembly's scene
    # 1002 in this style (bench/datagen/release_hold.py; docs/tasks.md).
    PROMPT_RETREAT = False
    RELEASE_SETTLE_S = 0.15
    COFFEE_PREP_RELEASE_DWELL = {True: (3, 5), False: (8, 12)}  # control periods, the privileged script's dwell

    def __init__(self, task: str, seed: int):
        self.task = get_task(task)
        self.seed = int(seed)
        self.rng = np.random.default_rng([self.seed, 0xDE70])
        self.style = DemoStyle.sample(self.rng)
        self.noise = SmoothNoise(self.rng)
        self.steps: list[DemoStep] = []
        self.types = {o.id: o.type for o in self.task.objects}

    # ------------------------------------------------------------------ recording
    def _obs(self, world) -> dict:
        return dict(time=float(world.time), joint_names=ARM_JOINTS, joint_positions=world.joint_positions().copy(),
                    ee_pose=world.ee_pose().as_array(), gripper_width=float(world.gripper_width()),
                    gripper_grasping=bool(world.is_grasping()),
                    object_poses={k: v.as_array() for k, v in world.object_poses().items()}, object_types=self.types,
                    object_joints=world.object_joints())

    def _send(self, world, target: Pose, gripper: float) -> None:
        obs = self._obs(world)
        self.steps.append(DemoStep(target=target.as_array(), gripper_command=float(gripper), **obs))
        world.step(target, gripper)
        self.cmd, self.grip = target, gripper

    @staticmethod
    def frames(world) -> dict[str, Pose]:
        """Object poses in the task's object frames (what the person sees; privileged here)."""
        return world.object_poses()

    # ------------------------------------------------------------------ primitives
    def move(self, world, goal: Pose, seconds: float, tremor: float = 1.0) -> None:
        """Min-jerk reach from the last command to goal; tremor fades out toward the goal."""
        n = int(np.ceil(seconds * self.style.speed * self.rng.uniform(0.9, 1.1) * CONTROL_HZ))
        for k, p in enumerate(reach(self.cmd, goal, n)):
            fade = np.sin(np.pi * (k + 1) / n) if n > 1 else 0.0
            self._send(world, Pose(p.position + self.noise(self.style.tremor * tremor) * fade, p.quaternion),
                       self.grip)

    def hold(self, world, seconds: float) -> None:
        for _ in range(max(1, int(round(seconds * CONTROL_HZ)))):
            self._send(world, self.cmd, self.grip)

    def maybe_hesitate(self, world) -> None:
        if self.rng.random() < self.style.hesitation_prob:
            self.hold(world, self.rng.uniform(0.15, 0.6))

    def gripper(self, world, command: float, seconds: float = 0.5) -> None:
        self.grip = command
        self.hold(world, seconds * self.rng.uniform(1.0, 1.3))

    # ------------------------------------------------------------------ skills
    def grasp_from_top(self, world, oid: str, point_local, yaw_base: float, yaw_period: float,
                       depth: float = 0.0) -> None:
        """Approach above `point_local` of object `oid`, descend, close. yaw: base + k*period."""
        obj = self.frames(world)[oid]
        point = obj.rotation.apply(point_local) + obj.position
        yaw = nearest_yaw(yaw_base, yaw_period, ee_yaw(self.cmd)) + self.style.yaw_error
        grasp = down_pose(point + [0.0, 0.0, -depth], yaw)
        h = self.style.approach_height
        pre = Pose(grasp.position + np.r_[self.style.approach_offset, h], grasp.quaternion)
        dist = np.linalg.norm(pre.position - self.cmd.position)
        self.move(world, pre, 0.8 + dist / 0.25)
        self.maybe_hesitate(world)
        near = Pose(grasp.position + [0, 0, 0.02], grasp.quaternion)
        self.move(world, near, 0.6 + h / 0.15, tremor=0.5)
        self.move(world, grasp, 0.5, tremor=0.2)
        self.hold(world, 0.2)
        self.gripper(world, CLOSED, self.GRASP_SETTLE_S[self.PROMPT_LIFT])

    def lift(self, world, height: float) -> None:
        """Straight up to `height` above the table; right after a grasp (see PROMPT_LIFT)."""
        if self.PROMPT_LIFT:
            dz, seconds = self.PROMPT_RISE
            self.move(world, Pose(self.cmd.position + [0.0, 0.0, dz], self.cmd.quaternion), seconds, tremor=0.3)
        up = Pose(np.r_[self.cmd.position[:2], TABLE_Z + height], self.cmd.quaternion)
        self.move(world, up, 0.5 + abs(height - self.cmd.position[2]) / 0.2, tremor=0.5)

    def object_in_hand(self, world, oid: str) -> np.ndarray:
        """T_EE^O, measured now (the grasp as it really is)."""
        return world.ee_pose().inverse().matrix() @ self.frames(world)[oid].matrix()

    def carry_object_to(self, world, oid: str, obj_goal: Pose, T_ee_obj: np.ndarray, seconds: float,
                        tremor: float = 1.0) -> None:
        """Move the EE so that the held object reaches obj_goal (through the measured grasp)."""
        T = obj_goal.matrix() @ np.linalg.inv(T_ee_obj)
        self.move(world, Pose.from_matrix(T), seconds, tremor)

    def retreat(self, world, dz: float = 0.10) -> None:
        self.move(world, Pose(self.cmd.position + [0, 0, dz], self.cmd.quaternion), 0.8, tremor=0.5)

    def release(self, world, dz: float = 0.10) -> None:
        """Open on the placed object and retreat `dz` straight up (see PROMPT_RETREAT)."""
        if not self.PROMPT_RETREAT:
            self.gripper(world, OPEN, 0.5)
            self.retreat(world, dz)
            return
        self.gripper(world, OPEN, self.RELEASE_SETTLE_S)
        rise, seconds = self.PROMPT_RISE
        self.move(world, Pose(self.cmd.position + [0.0, 0.0, rise], self.cmd.quaternion), seconds, tremor=0.3)
        self.retreat(world, dz - rise)

    # ------------------------------------------------------------------ tasks
    def _place_nut(self, world, nut_id: str, peg_id: str, period: float | None) -> None:
        nut_spec, peg_spec = self.task.object(nut_id), self.task.object(peg_id)
        self.lift(world, 0.20 + self.rng.uniform(0.0, 0.04))
        T_en = self.object_in_hand(world, nut_id)
        nut, peg = self.frames(world)[nut_id], self.frames(world)[peg_id]
        yaw = self._place_yaw(nut_spec, nut, peg, period)
        R = Rotation.from_euler("z", yaw)
        ring = R.apply(nut_spec.keypoint("ring_center"))
        top = peg.rotation.apply(peg_spec.keypoint("top")) + peg.position
        aim = np.r_[peg.position[:2] + self.style.place_offset, 0.0]

        def nut_at(z_ring: float) -> Pose:
            return Pose(np.r_[aim[:2], z_ring] - ring, R.as_quat())

        above = nut_at(top[2] + 0.05 + self.rng.uniform(0.0, 0.03))
        dist = np.linalg.norm(above.position - nut.position)
        self.carry_object_to(world, nut_id, above, T_en, 1.0 + dist / 0.22)
        self.hold(world, 0.2)
        T_en = self.object_in_hand(world, nut_id)  # look again before lowering onto the peg
        self.carry_object_to(world, nut_id, above, T_en, 0.4, tremor=0.3)
        self.maybe_hesitate(world)
        self.carry_object_to(world, nut_id, nut_at(top[2] + 0.01), T_en, 0.8, tremor=0.3)
        release = nut_at(TABLE_Z + nut_spec.half_extents[2] + NOMINAL.place_drop)
        self.carry_object_to(world, nut_id, release, T_en, 1.0, tremor=0.2)
        self.release(world)

    def _place_yaw(self, nut_spec, nut: Pose, peg: Pose, period: float | None) -> float:
        """The nut yaw a person would place with: the peg's symmetry (any yaw on a round peg), turning
        the wrist at most 135 deg, handle (and so the hand) as close to the robot as it can be: on
        robosuite's pegs, 0.79 m out, a handle pointing away puts the hand out of the Panda's reach."""
        y0, e0 = object_yaw(nut), ee_yaw(self.cmd)
        base = y0 if period is None else nearest_yaw(object_yaw(peg), period, y0)
        step = np.pi / 4 if period is None else period
        handle = nut_spec.keypoint("handle") - nut_spec.keypoint("ring_center")

        def cost(y: float) -> float:
            reach_xy = peg.position[:2] + Rotation.from_euler("z", y).apply(handle)[:2]
            wrist = abs(e0 + (y - y0))
            return float(np.linalg.norm(reach_xy)) + 0.01 * abs(y - y0) + (10.0 if wrist > MAX_EE_YAW else 0.0)
        cands = [base + k * step for k in range(-4, 5) if abs(base + k * step - y0) <= np.radians(135) + 1e-9]
        return min(cands, key=cost)

    def _grasp_nut(self, world, nut_id: str) -> None:
        nut = self.task.object(nut_id)
        yaw = object_yaw(self.frames(world)[nut_id])
        self.grasp_from_top(world, nut_id, nut.keypoint("handle"), yaw, np.pi,
                            depth=-NOMINAL.grasp_z_offset + self.rng.uniform(-0.002, 0.002))

    def _square(self, world) -> None:
        self._grasp_nut(world, "square_nut")
        self._place_nut(world, "square_nut", "square_peg", np.pi / 2)

    def _nut_assembly(self, world) -> None:
        self._grasp_nut(world, "square_nut")
        self._place_nut(world, "square_nut", "square_peg", np.pi / 2)
        self._grasp_nut(world, "round_nut")
        self._place_nut(world, "round_nut", "round_peg", None)

    def _pick_place(self, world) -> None:
        milk = self.task.object("milk")
        m = self.frames(world)["milk"]
        self.grasp_from_top(world, "milk", milk.keypoint("top"), object_yaw(m), np.pi / 2,
                            depth=NOMINAL.milk_grasp_depth + self.rng.uniform(0.0, 0.01))
        self.lift(world, 0.26 + self.rng.uniform(0.0, 0.04))
        T_em = self.object_in_hand(world, "milk")
        bin_spec = self.task.object("bin")
        b = self.frames(world)["bin"]
        m = self.frames(world)["milk"]
        R = Rotation.from_euler("z", object_yaw(m))
        floor = b.rotation.apply(bin_spec.keypoint("floor_center")) + b.position
        xy = b.position[:2] + self.rng.uniform(-0.02, 0.02, 2)
        above = Pose(np.r_[xy, floor[2] + 0.06 + milk.half_extents[2] + self.rng.uniform(0.04, 0.07)], R.as_quat())
        dist = np.linalg.norm(above.position - m.position)
        self.carry_object_to(world, "milk", above, T_em, 1.0 + dist / 0.22)
        self.maybe_hesitate(world)
        low = Pose(np.r_[xy, floor[2] + milk.half_extents[2] + NOMINAL.place_drop], R.as_quat())
        self.carry_object_to(world, "milk", low, T_em, 1.0, tremor=0.3)
        self.release(world, 0.12)

    def _threading(self, world) -> None:
        nd = self.task.object("needle")
        n = self.frames(world)["needle"]
        self.grasp_from_top(world, "needle", nd.keypoint("handle"), object_yaw(n), np.pi,
                            depth=-NOMINAL.grasp_z_offset + self.rng.uniform(-0.002, 0.002))
        self.lift(world, 0.20 + self.rng.uniform(0.0, 0.03))
        T_en = self.object_in_hand(world, "needle")
        tp = self.task.object("tripod")
        t = self.frames(world)["tripod"]
        n = self.frames(world)["needle"]
        ring = t.rotation.apply(tp.keypoint("ring_center")) + t.position
        yaw = nearest_yaw(object_yaw(t), np.pi, object_yaw(n))
        R = Rotation.from_euler("z", yaw)
        axis = R.apply([1.0, 0.0, 0.0])
        tip = R.apply(nd.keypoint("tip"))

        def needle_tip_at(p) -> Pose:
            return Pose(np.asarray(p) - tip, R.as_quat())

        lat = np.cross([0, 0, 1.0], axis) * self.style.place_offset[0]
        above = needle_tip_at(ring - axis * 0.07 + lat + [0, 0, 0.06 + self.rng.uniform(0.0, 0.03)])
        dist = np.linalg.norm(above.position - n.position)
        self.carry_object_to(world, "needle", above, T_en, 1.0 + dist / 0.22)
        pre = needle_tip_at(ring - axis * NOMINAL.insert_pre + lat)
        self.carry_object_to(world, "needle", pre, T_en, 1.0, tremor=0.2)
        self.hold(world, 0.3)
        T_en = self.object_in_hand(world, "needle")  # look again: the needle may have shifted in the grasp
        self.carry_object_to(world, "needle", pre, T_en, 0.5, tremor=0.1)
        self.maybe_hesitate(world)
        through = needle_tip_at(ring + axis * NOMINAL.insert_depth + lat)
        self.carry_object_to(world, "needle", through, T_en, 1.2, tremor=0.1)
        self.hold(world, 0.5)

    def _grasp_piece(self, world, oid: str, period: float) -> None:
        """Top-down across the piece's object x (piece 1's ridge, piece 2's knob), PIECE_GRASP_DEPTH below its top."""
        spec = self.task.object(oid)
        yaw = object_yaw(self.frames(world)[oid]) + np.pi / 2
        self.grasp_from_top(world, oid, spec.keypoint("top"), yaw, period,
                            depth=PIECE_GRASP_DEPTH + self.rng.uniform(-0.002, 0.002))

    def _insert_piece(self, world, oid: str, target_id: str, period: float, seat_z: float) -> None:
        """Carry the held piece high over target_id, turn it to the target's yaw (mod period), lower it
        (looking again above the target) and let go PIECE_DROP above its seat (centre height seat_z)."""
        self.lift(world, PIECE_TRAVEL + self.rng.uniform(0.0, 0.03))
        T_ep = self.object_in_hand(world, oid)
        cur, tgt = self.frames(world)[oid], self.frames(world)[target_id]
        R = Rotation.from_euler("z", nearest_yaw(object_yaw(tgt), period, object_yaw(cur)))
        aim = tgt.position[:2] + 0.5 * self.style.place_offset  # a careful aim: the slot has 3 mm a side

        def at(z: float) -> Pose:
            return Pose(np.r_[aim, z], R.as_quat())

        high = at(cur.position[2])
        self.carry_object_to(world, oid, high, T_ep, 1.0 + np.linalg.norm(high.position - cur.position) / 0.22)
        above = at(seat_z + 0.04 + self.rng.uniform(0.0, 0.03))
        self.carry_object_to(world, oid, above, T_ep, 1.0, tremor=0.3)
        self.hold(world, 0.2)
        T_ep = self.object_in_hand(world, oid)  # look again before lowering it in
        self.carry_object_to(world, oid, above, T_ep, 0.4, tremor=0.2)
        self.maybe_hesitate(world)
        self.carry_object_to(world, oid, at(seat_z + PIECE_DROP), T_ep, 1.2, tremor=0.1)
        self.hold(world, 0.2)
        self.release(world)

    def _three_piece_assembly(self, world) -> None:
        b, p1 = self.task.object("base"), self.task.object("piece_1")
        self._grasp_piece(world, "piece_1", np.pi)
        self._insert_piece(world, "piece_1", "base", np.pi / 2, TABLE_Z + p1.half_extents[2])
        self._grasp_piece(world, "piece_2", np.pi / 2)   # the knob is square
        seat = TABLE_Z + 2 * b.half_extents[2] + self.task.object("piece_2").half_extents[2]  # legs on the base
        self._insert_piece(world, "piece_2", "piece_1", np.pi, seat)

    def _coffee(self, world) -> None:
        """Grasp the pod from the top, lower it into the holder and let go, then push the lid shut."""
        pod, mach = self.task.object("coffee_pod"), self.task.object("coffee_machine")
        m = self.frames(world)["coffee_machine"]
        yaw = object_yaw(m) + np.pi / 2            # fingers across machine x, clear of the hinge and bracket
        self.grasp_from_top(world, "coffee_pod", pod.keypoint("grasp"), yaw, np.pi,
                            depth=self.rng.uniform(-0.002, 0.002))
        self.lift(world, 0.30 + self.rng.uniform(0.0, 0.03))
        T_ep = self.object_in_hand(world, "coffee_pod")
        cur = self.frames(world)["coffee_pod"]
        top = m.rotation.apply(mach.keypoint("holder_top")) + m.position
        aim = top[:2] + 0.3 * self.style.place_offset   # a careful aim: the cup has 3 mm around the pod

        def pod_bottom_at(z: float) -> Pose:
            return Pose(np.r_[aim, z + pod.half_extents[2]], cur.quaternion)

        high = pod_bottom_at(cur.position[2] - pod.half_extents[2])
        self.carry_object_to(world, "coffee_pod", high, T_ep, 1.0 + np.linalg.norm(high.position - cur.position) / 0.22)
        above = pod_bottom_at(top[2] + 0.03 + self.rng.uniform(0.0, 0.02))
        self.carry_object_to(world, "coffee_pod", above, T_ep, 1.0, tremor=0.3)
        self.hold(world, 0.2)
        T_ep = self.object_in_hand(world, "coffee_pod")   # look again before lowering it in
        self.carry_object_to(world, "coffee_pod", above, T_ep, 0.4, tremor=0.2)
        self.maybe_hesitate(world)
        self.carry_object_to(world, "coffee_pod", pod_bottom_at(top[2] - POD_RELEASE_IN), T_ep, 1.2, tremor=0.1)
        self.hold(world, 0.2)
        self.release(world, 0.12)
        self._close_lid(world, m)

    def _close_lid(self, world, m: Pose) -> None:
        """From behind the open lid (machine -y), the open hand, its fingers in a row along machine y, sweeps
        along machine +y over the hinge: the lid tips past upright and falls shut. No second close, so the
        skill's gripper events stay one grasp and one release."""
        yaw = nearest_yaw(object_yaw(m), np.pi, ee_yaw(self.cmd)) if self.LID_PUSH_TURNS else ee_yaw(self.cmd)
        q = down_pose(np.zeros(3), yaw).quaternion
        dz = 0.0 if self.LID_PUSH_TURNS else -0.04

        def at(y: float, z: float) -> Pose:
            return Pose(m.rotation.apply([0.0, y, z + dz]) + m.position, q)
        y0 = LID_PUSH_FROM + self.rng.uniform(-0.01, 0.0)
        self.move(world, at(y0, LID_PUSH_Z + 0.09), 1.2)
        self.move(world, at(y0, LID_PUSH_Z + self.rng.uniform(-0.005, 0.005)), 0.8, tremor=0.5)
        self.maybe_hesitate(world)
        self.move(world, at(LID_PUSH_TO, LID_PUSH_Z), 2.0, tremor=0.3)
        self.retreat(world, 0.10)

    def _coffee_preparation(self, world) -> None:
        """The privileged script's five skills (core/tasks/scripted_coffee_prep.py) at this demo's pace: its speeds
        divided by the style's slowness, its approach height and dwell times the style's (see _PersonAsEnv)."""
        dwell = self.COFFEE_PREP_GRASP_DWELL[self.PROMPT_LIFT]
        prm = replace(NOMINAL, speed=NOMINAL.speed / self.style.speed, slow_speed=NOMINAL.slow_speed / self.style.speed,
                      approach_height=self.style.approach_height, grasp_dwell=int(self.rng.integers(*dwell)),
                      release_dwell=int(self.rng.integers(*self.COFFEE_PREP_RELEASE_DWELL[self.PROMPT_RETREAT])),
                      settle=int(self.rng.integers(3, 7)))
        scripted_coffee_prep.run(Scripter(_PersonAsEnv(self, world), prm, self.rng))

    PLANS: dict[str, Callable] = {"Square": _square, "NutAssembly": _nut_assembly, "PickPlace": _pick_place,
                                  "Threading": _threading, "ThreePieceAssembly": _three_piece_assembly,
                                  "Coffee": _coffee, "CoffeePreparation": _coffee_preparation}

    def run(self, world, variant: str, scene_seed: int) -> DemoRollout:
        """Reset `world` to (task, variant, scene_seed), perform the task, return the recorded rollout."""
        world.reset(self.task.name, variant, scene_seed)
        self.steps = []
        self.cmd, self.grip = world.ee_pose(), OPEN
        self.hold(world, self.rng.uniform(0.3, 0.8))  # the person takes a look first
        self.PLANS[self.task.name](self, world)
        self.hold(world, 0.3)
        return DemoRollout(self.task.name, variant, int(scene_seed), tuple(self.steps), bool(world.task_success()),
                           self.seed, {"style": repr(self.style)})

"""The planner's start repairs (this project's `extras`, off in the paper profile): what to do when
a plan starts in contact or in collision, as a replayed skill often leaves the arm.

- a hand against a fixture backs out along its retreat (doubled to 10 cm if still touching);
- an arm grazing an obstacle escapes along its null space (hand and held object stay put);
- where none escapes and the wrist alone is at the released object or its support, the wrist may
  touch them on the retreat as the hand may;
- a retreat IK cannot follow is shortened to where it holds, or preceded by a self-motion.

A mixin of MotionPlanner (planner.py): it uses the planner's kin, ik, cm and retreat_distance.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .phases import CartesianPathError, cartesian_line

# Each repair is noted in PlanResult.message by its phrase (planner.py writes the notes): one table, so a
# reader that counts them (bench/datagen/diagnose.py) matches what the planner writes.
START_REPAIRS = {"hand_backout": "start: hand touches", "wrist_backout": "start: wrist touches",
                 "null_space_escape": "start in collision: moved", "retreat_skipped": "retreat skipped",
                 "retreat_shortened": "retreat shortened",
                 "self_motion_retreat": "null space first, then retreated"}


class StartRepairs:
    def _touching_hand(self, q0, allow, collides) -> tuple[str, ...]:
        """Scene boxes whose contact with the hand alone makes the start collide (empty if allowing
        every hand contact would still leave it colliding: then the arm or the held object hits)."""
        names = tuple(dict.fromkeys(b.name for b in self.cm.boxes if b.name not in allow.hand_names()))
        if not names or collides(q0[None], replace(allow, hand_object=allow.hand_names() + names))[0]:
            return ()
        return tuple(n for n in names
                     if collides(q0[None], replace(allow, hand_object=allow.hand_names() + tuple(m for m in names if m != n)))[0])

    @staticmethod
    def _wrist_clears(q0, allow, collides) -> bool:
        """Whether letting the wrist (panda_link7) touch what the hand may touch -- the object just
        released and what it rests on -- clears the start. A nut pushed down its peg with the hand
        closed leaves the wrist beside the peg's top, inside the spheres' padding, where no
        self-motion gets it out (bench/results/hsp_skill_diagnosis.json, docs/hsp.md); the
        retreat lifts it away along the hand's axis."""
        return bool(allow.hand_names()) and not collides(q0[None], replace(allow, wrist=True))[0]

    def _null_space_escape(self, q0, blocked, step: float = 0.02, reach: float = 0.5) -> np.ndarray | None:
        """A start in collision (the elbow grazing an obstacle after a replayed skill, inside the
        spheres' padding) moved along the arm's self-motion, which keeps the hand -- and what it
        holds -- where it is, until `blocked(q)` is false (clear). MoveIt's FixStartStateCollision
        jiggles the joints at random instead; that would drag a grasped object. Returns the path
        (q0 first) or None."""
        T0 = self.kin.fk(q0)
        best = None
        for sign in (1.0, -1.0):
            path, q, prev = [q0], q0, None
            for _ in range(int(2 * reach / step)):  # a step blocked at a joint limit makes no progress
                J = self.kin.jacobian(q)
                n = np.linalg.svd(J)[2][-1]  # the 7-DOF arm's one null-space direction
                n = n * (sign if prev is None else np.sign(n @ prev) or 1.0)
                prev = n
                q = self.ik.solve_local(T0, q + step * n / np.abs(n).max())
                if q is None or not self.kin.within_limits(q) or np.abs(q - q0).max() > reach:
                    break
                path.append(q)
                if not blocked(q):
                    if best is None or len(path) < len(best):
                        best = path
                    break
        return None if best is None else np.array(best)

    def _self_motion_retreat(self, q0, edge_free, allow, collides) -> np.ndarray | None:
        """Where IK loses the retreat line at once (the wrist at its joint limit after a low grasp)
        and the start is in contact, move along the self-motion -- hand and held object stay put --
        until the whole line is followable and clear, then retreat from there."""
        lines: dict[bytes, np.ndarray] = {}

        def line_blocked(q) -> bool:
            try:
                line = cartesian_line(self.kin, self.ik, q, -self.retreat_distance)
            except CartesianPathError:
                return True
            if not self._ends_clear(line, edge_free, allow, collides):
                return True
            lines[q.tobytes()] = line
            return False

        escape = self._null_space_escape(q0, line_blocked)
        if escape is None or not self._segment_free(escape, edge_free, allow):
            return None
        return np.vstack([escape[:-1], lines[escape[-1].tobytes()]])

    @staticmethod
    def _segment_free(path: np.ndarray, edge_free, allow) -> bool:
        return all(edge_free(a, b, allow) for a, b in zip(path[:-1], path[1:]))

    def _ends_clear(self, path: np.ndarray, edge_free, allow, collides) -> bool:
        """A retreat that may pass through the start's allowed contacts but ends free of all."""
        return not collides(path[-1:])[0] and self._segment_free(path, edge_free, allow)

    def _partial_retreat(self, q0, edge_free, allow, collides) -> np.ndarray | None:
        """The retreat line as far as IK follows it, if that ends clear of every contact."""
        try:
            path = cartesian_line(self.kin, self.ik, q0, -self.retreat_distance, partial=True)
        except CartesianPathError:
            return None
        return path if len(path) >= 2 and self._ends_clear(path, edge_free, allow, collides) else None

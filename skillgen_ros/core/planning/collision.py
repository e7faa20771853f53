"""Sphere-based collision model of the Panda against boxes, a point cloud, the table and itself.

The robot is the set of spheres fitted offline to its collision meshes (sphere_fit.py ->
panda_spheres.yaml). A query takes many configurations at once: one numba call computes every
sphere centre and checks boxes, the table half-space and self-collision pairs; one cKDTree query
checks all centres against the point cloud. That is how whole edges are validated in one call.

Allowed contacts (the paper's retreat/approach rule) are an `AllowedContacts`: the hand may touch
the manipulated object, and the attached object may touch its support. For boxes this masks
sphere/box pairs; for a cloud, points inside the (padded) allowed box are ignored for those
spheres.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
import yaml
from scipy.spatial import cKDTree

from ..errors import InvalidInputError
from ..geometry import invert
from ..robot import HAND_LINK, TABLE_Z
from . import kernels
from .kinematics import LINKS, PandaKinematics
from .occlusion import REFINE, DepthView, hidden_space

SPHERES_FILE = Path(__file__).with_name("panda_spheres.yaml")
HAND = LINKS.index(HAND_LINK)
WRIST = LINKS.index("panda_link7")  # the link above the hand: beside a peg's top after a low place
ATTACHED = len(LINKS)  # group id of attached-object spheres
FILL_XY_DIV = 2  # heightmap columns are voxel / FILL_XY_DIV wide (points every voxel up them)
HIDDEN_REFINE = REFINE  # hidden cells left after certification are halved and certified again this often
SHADOW_PX = 4.0  # hidden space behind a surface, in pixel footprints (docs/planning.md: measured)


@dataclass(frozen=True, eq=False)  # identity equality: fields are arrays
class Box:
    """An oriented box obstacle: world pose (4x4) and half extents (3,)."""

    name: str
    pose: np.ndarray
    half_extents: np.ndarray

    def __post_init__(self):
        T = np.asarray(self.pose, float)
        h = np.asarray(self.half_extents, float).reshape(-1)
        if T.shape != (4, 4) or h.shape != (3,) or not (np.all(np.isfinite(T)) and np.all(h >= 0)):
            raise InvalidInputError(f"box {self.name!r}: need a 4x4 pose and 3 half extents >= 0")
        object.__setattr__(self, "pose", T)
        object.__setattr__(self, "half_extents", h)

    def contains(self, points: np.ndarray, pad: float = 0.0) -> np.ndarray:
        local = (np.asarray(points, float) - self.pose[:3, 3]) @ self.pose[:3, :3]
        return np.all(np.abs(local) <= self.half_extents + pad, axis=1)


@dataclass(frozen=True, eq=False)
class AttachedObject:
    """A grasped object as spheres (M,4: x, y, z, r) in the EE (panda_grasptarget) frame."""

    name: str
    spheres: np.ndarray
    support: str = "table"  # what it rests on when released (contact allowed on approach)

    @staticmethod
    def from_box(name: str, half_extents, T_ee_obj: np.ndarray, spacing: float = 0.03,
                 support: str = "table") -> "AttachedObject":
        """Fill a box with a grid of spheres whose union covers it."""
        h = np.asarray(half_extents, float)
        n = np.maximum(1, np.ceil(2 * h / spacing)).astype(int)
        axes = [np.linspace(-hi + hi / ni, hi - hi / ni, ni) for hi, ni in zip(h, n)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
        r = float(np.linalg.norm(h / n))  # half-diagonal of one cell
        T = np.asarray(T_ee_obj, float)
        c = grid @ T[:3, :3].T + T[:3, 3]
        return AttachedObject(name, np.hstack([c, np.full((len(c), 1), r)]), support)

    @staticmethod
    def from_points(name: str, points_ee: np.ndarray, radius: float = 0.01,
                    support: str = "table") -> "AttachedObject":
        p = np.asarray(points_ee, float).reshape(-1, 3)
        return AttachedObject(name, np.hstack([p, np.full((len(p), 1), radius)]), support)


@dataclass(frozen=True)
class AllowedContacts:
    """Contacts tolerated in retreat/approach: hand <-> `hand_object`, attached <-> `support`.

    hand_object may name several boxes (a tuple), e.g. a nut just released onto a peg and the peg,
    or every manipulated object of the scene: the paper ignores robot/manipulated-object and
    manipulated-object/environment contacts in these short phases (its Appendix, "Motion Planning").
    held_free: the held object may touch anything, the table included (that second rule).
    wrist: panda_link7 may touch them too (a start repair, planner.py: a nut pushed down its peg
    leaves the wrist beside the peg's top, inside the spheres' padding)."""

    hand_object: str | tuple[str, ...] | None = None
    support: str | None = None
    wrist: bool = False
    held_free: bool = False

    def hand_names(self) -> tuple[str, ...]:
        h = self.hand_object
        return () if h is None else (h,) if isinstance(h, str) else tuple(h)


NO_CONTACTS = AllowedContacts()


def phase_contacts(cm: "CollisionModel", start_objects, goal_objects, movable: tuple[str, ...] | None,
                   held: str | None = None, start_support: str | None = None,
                   goal_support: str | None = None) -> tuple[AllowedContacts, AllowedContacts]:
    """What the retreat (start) and the approach (goal) may touch: the hand the named objects (None
    names skipped) and, for a held object, its support; with `movable` (the paper's rule) the hand
    also every manipulated object the scene has a box for, and a held object anything."""
    known = {b.name for b in cm.boxes}  # a name without geometry would drop the cloud (_tree)
    more = tuple(m for m in movable or () if m in known and m != held)

    def names(objects):
        n = tuple(dict.fromkeys(x for x in (*objects, *more) if x))
        return n[0] if len(n) == 1 else n or None  # one name stays a string
    held_free = held is not None and movable is not None
    return (AllowedContacts(names(start_objects), support=start_support, held_free=held_free),
            AllowedContacts(names(goal_objects), support=goal_support, held_free=held_free))


@dataclass(frozen=True)
class _Spheres:
    link: np.ndarray  # index into LINKS of the frame each sphere moves with
    centre: np.ndarray
    radius: np.ndarray
    group: np.ndarray  # LINKS index, or ATTACHED


def heightmap_fill(P: np.ndarray, floor: float, voxel: float, z_step: float | None = None) -> np.ndarray:
    """Columns on a `voxel` (x, y) grid, points every `z_step` (default voxel) from `floor`
    (included: an object's bottom edge stands on it) up to the highest point of each cell."""
    z_step = voxel if z_step is None else z_step
    ij = np.floor(P[:, :2] / voxel).astype(np.int64)
    lo = ij.min(axis=0)
    span = int(ij[:, 1].max() - lo[1]) + 1
    keys, inv = np.unique((ij[:, 0] - lo[0]) * span + (ij[:, 1] - lo[1]), return_inverse=True)  # 1-D: fast
    cells = np.column_stack([keys // span + lo[0], keys % span + lo[1]])
    top = np.full(len(cells), -np.inf)
    np.maximum.at(top, inv.reshape(-1), P[:, 2])
    n = np.maximum(1, np.ceil((top - floor) / z_step).astype(np.int64)) + 1
    rep = np.repeat(np.arange(len(cells)), n)
    k = np.arange(len(rep)) - np.repeat(np.cumsum(n) - n, n)
    z = np.minimum(floor + k * z_step, top[rep])  # from the table itself up to the top
    xy = (cells[rep] + 0.5) * voxel
    return np.column_stack([xy, z])


class CollisionModel:
    """Robot spheres vs scene boxes, an optional point cloud, the table (z < table_z) and self."""

    def __init__(self, kin: PandaKinematics, margin: float = 0.005, cloud_margin: float = 0.01,
                 table_z: float | None = TABLE_Z, spheres_file: Path = SPHERES_FILE):
        self.kin = kin
        self.margin = float(margin)
        self.cloud_margin = float(cloud_margin)
        self.table_z = table_z
        data = yaml.safe_load(Path(spheres_file).read_text())
        link, cen, rad = [], [], []
        for name, L in data["links"].items():
            link += [LINKS.index(name)] * len(L["radii"])
            cen += L["centers"]
            rad += L["radii"]
        link = np.array(link, np.int64)
        self.robot = _Spheres(link, np.array(cen, float), np.array(rad, float), link.copy())
        self.link_pairs = [tuple(p) for p in data.get("self_collision_pairs", [])]
        self.boxes: tuple[Box, ...] = ()
        self.box_obstacles = True
        self.cloud: np.ndarray = np.empty((0, 3))
        self._trees: dict = {}
        self._cache_key = None
        self._cache = None
        self.in_collision(np.zeros((1, 7)))  # compile/load the numba kernels up front
        self.reach = self._joint_reach()

    def _joint_reach(self, n: int = 2000) -> np.ndarray:
        """R_j: an upper bound on the distance from joint j's origin to any robot point it moves
        (sampled over random configurations, +10% and 1 cm slack). A joint step dq_j then moves
        no robot point by more than |dq_j| R_j."""
        Q = np.random.default_rng(0).uniform(self.kin.lower, self.kin.upper, (n, 7))
        F = self.kin.joint_frames_batch(Q)
        C, R, _ = self._spheres_world(Q)
        reach = np.zeros(7)
        parent = self.kin._link_parent[self.robot.link]  # joint that moves each sphere
        for j in range(7):
            down = parent >= j + 1
            d = np.linalg.norm(C[:, down] - F[:, j + 1, None, :3, 3], axis=2) + R[down]
            reach[j] = d.max()
        return reach * 1.1 + 0.01

    # -- scene -------------------------------------------------------------------------------
    def set_boxes(self, boxes, as_obstacles: bool = True) -> None:
        """Scene boxes. With as_obstacles=False (point-cloud mode) they are not checked; they only
        localise allowed contacts in the cloud (which points belong to the manipulated object)."""
        self.boxes = tuple(boxes)
        self.box_obstacles = bool(as_obstacles)
        self._cache_key = None
        self._trees = {}

    def set_point_cloud(self, points, self_filter_q=None, attached: AttachedObject | None = None,
                        filter_pad: float = 0.02, fill_below: bool = False,
                        voxel: float = 0.01, views: Sequence[DepthView] = (),
                        shadow_px: float | None = SHADOW_PX, hidden_refine: int = HIDDEN_REFINE) -> int:
        """Use `points` (N,3, world) as obstacles; returns how many are kept.

        Dropped: non-finite points, the table top (z <= table_z + 5 mm; the table is the
        half-space already), and points inside the robot's (and attached object's) spheres at
        `self_filter_q` padded by `filter_pad` -- that is the robot seeing itself.
        fill_below: treat the space under every observed point, down to the table, as occupied
        (the 2.5-D heightmap assumption of tabletop scenes: a camera sees the tops and fronts of
        objects, not their backs). Points are then put on columns voxel / FILL_XY_DIV wide, a
        point every `voxel` metres up each.
        views: the depth images the points came from (occlusion.DepthView); the space hidden
        behind what they saw, unless another view saw it free, is occupied too (cells of `voxel`,
        those left halved `hidden_refine` times), `shadow_px` pixel footprints deep (None: all of
        it, down to the table). With fill_below, the hidden cells are filled below as well: the
        unseen strip at a box's far edge, between its last seen top pixel and the true edge, then
        reaches the table.
        """
        P = np.asarray(points, float).reshape(-1, 3)
        P = P[np.all(np.isfinite(P), axis=1)]
        floor = self.table_z if self.table_z is not None else -np.inf
        P = P[P[:, 2] > floor + 0.005]
        on_robot = None
        if self_filter_q is not None:
            C, R = self._spheres_world(np.asarray(self_filter_q, float).reshape(1, 7), attached)[:2]

            def on_robot(X):  # noqa: E306 -- inside some padded robot sphere
                hit = np.zeros(len(X), bool)
                if len(X):
                    for i in cKDTree(X).query_ball_point(C[0], R + filter_pad):
                        hit[i] = True
                return hit
            if len(P):
                P = P[~on_robot(P)]
        if len(views) and self.table_z is not None:
            if self.cloud_margin < 0.5 * np.sqrt(3.0) * voxel:
                raise InvalidInputError(f"cloud margin {self.cloud_margin} m does not cover a {voxel} m cell")
            H = hidden_space(views, self.table_z, on_robot, voxel, shadow_px=shadow_px, refine=hidden_refine)
            if on_robot is not None and len(H):
                H = H[~on_robot(H)]  # where the robot is, is its own space
            P = np.vstack([P, H])
        if fill_below and len(P) and self.table_z is not None:
            # columns half a cell wide: a point moves at most 3.5 mm sideways (a 1 cm grid moved a
            # box's edge 7 mm out and refused goals the raw cloud allowed; bench/planning)
            P = heightmap_fill(P, self.table_z, voxel / FILL_XY_DIV, z_step=voxel)
        self.cloud = P
        self._trees = {}
        return len(P)

    def _tree(self, skip_box):
        """KD-tree of the cloud, without the points inside the box(es) named `skip_box` (a name or a
        tuple of names; padded 2 cm)."""
        if skip_box not in self._trees:
            P = self.cloud
            names = () if skip_box is None else (skip_box,) if isinstance(skip_box, str) else tuple(skip_box)
            for name in names:
                if not len(P):
                    break
                boxes = [b for b in self.boxes if b.name == name]
                if not boxes:  # unknown geometry: the allowed contact cannot be localised, so ignore the cloud
                    P = P[:0]
                    break
                for box in boxes:
                    P = P[~box.contains(P, pad=0.02)]
            self._trees[skip_box] = cKDTree(P) if len(P) else None
        return self._trees[skip_box]

    # -- spheres -----------------------------------------------------------------------------
    def _spheres(self, attached: AttachedObject | None):
        r = self.robot
        if attached is None:
            return r.link, r.centre, r.radius, r.group
        s = np.asarray(attached.spheres, float).reshape(-1, 4)
        # express EE-frame spheres in the hand frame: EE = hand @ T_hand_ee
        T_he = invert(self.kin._link_T[HAND]) @ self.kin._ee_T
        c = s[:, :3] @ T_he[:3, :3].T + T_he[:3, 3]
        n = len(s)
        return (np.concatenate([r.link, np.full(n, HAND)]), np.vstack([r.centre, c]),
                np.concatenate([r.radius, s[:, 3]]), np.concatenate([r.group, np.full(n, ATTACHED)]))

    def _spheres_world(self, Q, attached=None):
        link, cen, rad, group = self._spheres(attached)
        C = kernels.sphere_centres(np.ascontiguousarray(Q, float), self.kin._joint_T,
                                   self.kin._link_parent, self.kin._link_T, link, cen)
        return C, rad, group

    def sphere_world(self, q, attached=None) -> np.ndarray:
        """(S,4) world spheres at q, for visualisation and tests."""
        C, R, _ = self._spheres_world(np.asarray(q, float).reshape(1, 7), attached)
        return np.hstack([C[0], R[:, None]])

    def _static(self, attached, allow: AllowedContacts):
        key = (attached, allow, self.boxes, self.box_obstacles)  # holds refs: no id reuse
        if key == self._cache_key:
            return self._cache
        link, cen, rad, group = self._spheres(attached)
        boxes = self.boxes if self.box_obstacles else ()
        B = len(boxes)
        inv = np.stack([invert(b.pose) for b in boxes]) if B else np.zeros((0, 4, 4))
        half = np.stack([b.half_extents for b in boxes]) if B else np.zeros((0, 3))
        skip = np.zeros((len(rad), B), np.bool_)
        hand = (group == HAND) | ((group == WRIST) & allow.wrist)
        for j, b in enumerate(boxes):
            if attached is not None and b.name == attached.name:
                skip[:, j] = True  # the held object is not an obstacle
            if b.name in allow.hand_names():
                skip[hand, j] = True
                skip[group == ATTACHED, j] = True
            if allow.support is not None and b.name == allow.support:
                skip[group == ATTACHED, j] = True
        if allow.held_free:
            skip[group == ATTACHED, :] = True
        table = group != LINKS.index("panda_link0")
        if allow.support == "table" or allow.held_free:
            table &= group != ATTACHED
        if allow.hand_object is not None:  # grasping near the table: fingertips may graze it
            table &= group != HAND
        if self.table_z is None:
            table[:] = False
        ia, ib = [], []
        pairs = set(self.link_pairs)
        for i in range(len(rad)):
            for j in range(i + 1, len(rad)):
                gi, gj = group[i], group[j]
                if (min(gi, gj), max(gi, gj)) in pairs:
                    ia.append(i)
                    ib.append(j)
                elif ATTACHED in (gi, gj) and min(gi, gj) <= LINKS.index("panda_link5"):
                    ia.append(i)
                    ib.append(j)
        self._cache_key = key
        self._cache = (rad, group, inv, half, skip, table, np.array(ia, np.int64), np.array(ib, np.int64))
        return self._cache

    # -- queries -----------------------------------------------------------------------------
    def in_collision(self, Q, attached: AttachedObject | None = None,
                     allow: AllowedContacts = NO_CONTACTS) -> np.ndarray:
        """(N,7) -> (N,) bool, True where the configuration collides."""
        Q = np.ascontiguousarray(np.asarray(Q, float).reshape(-1, 7))
        rad, group, inv, half, skip, table, ia, ib = self._static(attached, allow)
        C, _, _ = self._spheres_world(Q, attached)
        tz = -np.inf if self.table_z is None else float(self.table_z)
        hit = kernels.collide_spheres(C, rad, ia, ib, inv, half, skip, tz, table, self.margin)
        if len(self.cloud) and not np.all(hit):
            hit |= self._cloud_hits(C, rad, group, attached, allow)
        return hit

    def _cloud_hits(self, C, rad, group, attached, allow) -> np.ndarray:
        """Arm spheres vs the whole cloud; hand spheres without the allowed object's points;
        attached spheres without the support's points (the table is the half-space)."""
        n = C.shape[0]
        hit = np.zeros(n, bool)
        support = allow.support if allow.support != "table" else None
        wrist = (group == WRIST) & allow.wrist
        sets = (((group < HAND) & ~wrist, None), ((group == HAND) | wrist, allow.hand_object),
                ((group == ATTACHED) & (not allow.held_free), support))
        for mask, skip_box in sets:
            if not np.any(mask):
                continue
            tree = self._tree(skip_box)
            if tree is None:
                continue
            pts = C[:, mask].reshape(-1, 3)
            r = np.tile(rad[mask], n) + self.cloud_margin
            d, _ = tree.query(pts, distance_upper_bound=float(r.max()))
            hit |= np.any((d < r).reshape(n, -1), axis=1)
        return hit

    def motion_samples(self, q0, q1, attached: AttachedObject | None = None,
                       step: float | None = None) -> np.ndarray:
        """Configurations along the joint-space segment, spaced so that no robot (or attached)
        point moves more than `step` metres between neighbours (default 2 x margin). A sphere
        check with margin >= step/2 at the samples then covers the continuous motion."""
        q0, q1 = np.asarray(q0, float), np.asarray(q1, float)
        step = 2.0 * min(self.margin, self.cloud_margin) if step is None else float(step)
        reach = self.reach
        if attached is not None:
            s = np.asarray(attached.spheres, float).reshape(-1, 4)
            reach = reach + float(np.max(np.linalg.norm(s[:, :3], axis=1) + s[:, 3]))
        travel = float(np.abs(q1 - q0) @ reach)
        n = max(2, int(np.ceil(travel / max(step, 1e-4))) + 1)
        return q0 + np.linspace(0.0, 1.0, n)[:, None] * (q1 - q0)

    def check_motion(self, q0, q1, attached: AttachedObject | None = None,
                     allow: AllowedContacts = NO_CONTACTS) -> bool:
        """True if the straight joint-space segment is free (continuous, see motion_samples).
        Every 8th sample is checked first: most blocked edges fail there, cheaply."""
        Q = self.motion_samples(q0, q1, attached)
        if len(Q) > 16 and np.any(self.in_collision(Q[::8], attached, allow)):
            return False
        return not bool(np.any(self.in_collision(Q, attached, allow)))

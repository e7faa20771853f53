"""Objects inside articulated fixtures: a second look without the fixture's own points.

Coffee Prep's pod lies in a drawer. Once the drawer is open the front camera sees ~45 points of the
pod, but DBSCAN joins them to the tray's walls and bottom, and that cluster matches no model: the
pod is reported missing. The fixture's model cannot explain the tray either, since it shows the links
at their reset values (the drawer shut). The scene knows better: the fixture's pose was just
estimated, and its joint values come from the driver (`object_joint_states`) or the sim. So, when a
required object is missing and an articulated fixture was found, its parts and links are posed at the
current joint values, the points inside them (plus a few mm) are dropped, and every movable object is
identified again in what is left. An opened drawer is itself not found (its model shows it shut), so a
fixture seen before lends its earlier pose (`known`: fixtures do not move; the caller keeps them per
scene, e.g. in a SceneFixtures). On Coffee Prep D0 seeds 0-2 with the drawer 20 cm open this finds the
pod within 1 mm; without the removal it is missing in all three.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..geometry import Pose
from ..planning.articulated import object_boxes
from ..tasks.spec import ObjectSpec
from .models import ObjectModel
from .pipeline import PerceptionParams, PerceptionResult, PerceptionStatus, estimate_poses

FIXTURE_PAD = 0.003  # m: points this close outside a fixture's part still belong to it (depth noise ~1 mm)


def estimate_with_fixtures(points: np.ndarray, models: Mapping[str, ObjectModel], specs: Mapping[str, ObjectSpec],
                           params: PerceptionParams = PerceptionParams(), camera_position=None,
                           object_ids: Sequence[str] | None = None, joints: Mapping[str, float] | None = None,
                           frame: str | None = None, known: Mapping[str, Pose] | None = None) -> PerceptionResult:
    """estimate_poses, then the second look (module docstring) when a required object is missing.

    specs: the scene's ObjectSpecs by id (which objects are articulated and their parts); joints: the
    scene's joint values ({joint_key: value}; a joint without one is at its reset value); known: poses of
    this scene's fixtures seen before, used for one not found now. The second look re-identifies every
    movable object: where a fixture went unexplained, the first look may have fitted a movable object's
    model to a piece of it (the pod's to the machine's cup-shaped holder, 14 cm over the mug, when the lid
    was open). A fixture not found now stays missing in the result (the caller decides whether an earlier
    belief will do)."""
    first = estimate_poses(points, models, params, camera_position, object_ids, frame)
    wanted = list(object_ids) if object_ids else list(models)
    articulated = {i for i, o in specs.items() if o.joints and o.is_fixture}
    where = {**{i: p for i, p in (known or {}).items() if i in articulated},
             **{i: e.pose for i, e in first.poses.items() if i in articulated}}
    movable = [i for i in wanted if i not in articulated]
    if first.status is not PerceptionStatus.OBJECT_MISSING or not where or not movable:
        return first
    pts = np.asarray(points, float).reshape(-1, 3)
    found = sorted(where)
    inside = np.zeros(len(pts), bool)
    for b in (b for i in found for b in object_boxes(specs[i], where[i], joints)):
        inside |= b.contains(pts, FIXTURE_PAD)
    # every movable model competes (the mug claims its own cluster); a movable object the second look
    # misses keeps what the first look found
    second = estimate_poses(pts[~inside], {i: m for i, m in models.items() if i not in articulated}, params,
                            camera_position, movable, frame)
    poses = {**first.poses, **{i: e for i, e in second.poses.items() if i in movable}}
    still = [i for i in wanted if i not in poses]
    status, msg = ((PerceptionStatus.OK, f"{len(poses)} object(s), {movable} looked for again without "
                    f"{found}'s points") if not still else
                   (PerceptionStatus.OBJECT_MISSING, f"not found in view: {still} (also without {found}'s points)"))
    return PerceptionResult(status, msg, poses, first.obstacles, first.clusters, first.unknown_clusters, first.table,
                            {**first.timings, "fixtures_second_look": second.timings.get("total", 0.0)})


class SceneFixtures:
    """Fixture poses seen in one scene, for `known` above: fixtures do not move within a scene, but
    the next scene (a D1/D2 reset) puts them elsewhere, and a pose kept from it would pose the
    removal boxes there. A look names its scene (the graph: the reset state's stamp); a look in
    another scene starts from nothing. `scene=None` keeps what was seen until clear() (a caller
    that cannot name its scene)."""

    def __init__(self):
        self.scene, self.poses = None, {}

    def known(self, scene=None) -> dict[str, Pose]:
        """The poses seen so far in `scene` (forgetting another scene's)."""
        if scene is not None and scene != self.scene:
            self.scene, self.poses = scene, {}
        return dict(self.poses)

    def update(self, scene, result: PerceptionResult, specs: Mapping[str, ObjectSpec]) -> None:
        """Keep the fixtures `result` found in `scene` (only if it is still the current one)."""
        if scene is None or scene == self.scene:
            self.poses.update({i: e.pose for i, e in result.poses.items() if specs[i].is_fixture})

    def clear(self) -> None:
        self.scene, self.poses = None, {}

"""In-process GenerationEnv: SimWorld + MotionPlanner + perception in one Python process.

The same Algorithm 1 (attempt.py) runs over this env or over the ROS graph (nodes/datagen.py);
this one is the baseline that measures the graph's overhead and the throughput ceiling, and it
is what shards of a large run use. Perception is explicit: "estimate" runs the model-based
pipeline on the front camera's cloud, "ground_truth" reads the sim's true poses (an ablation,
never a silent fallback). Collision geometry for planning comes from the scene's object parts
placed at the perceived poses ("scene") or from the camera cloud ("cloud"). Observations carry
both the sim's true object poses (what a ground_truth dataset records) and the belief the attempt
acts on (estimates, a grasped object moved with the hand), stamped with the sim time.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError, SkillGenError
from ..geometry import Pose
from ..planning.articulated import attached_from_parts, object_boxes, support_below
from ..planning.collision import AttachedObject, CollisionModel
from ..planning.occlusion import DepthView
from ..planning.ik import IKSolver
from ..planning.kinematics import PandaKinematics
from ..planning.planner import Mode, MotionPlanner, PlanStatus
from ..sim.camera import CameraConfig
from ..sim.contact_model import DEFAULT_CONTACT_MODEL, contact_settings
from ..sim.world import SimWorld
from ..tasks.suite import get_task
from .episode import Observation
from .grasp import CLOSE_PERIODS, LookBeliefs, GraspTracker, carriable, unaccounted

PERCEPTION_MODES = ("estimate", "ground_truth")
COLLISION_SOURCES = ("scene", "cloud")


@dataclass(frozen=True)
class SimEnvConfig:
    perception: str = "estimate"
    collision: str = "scene"
    # a wall-time cap only (iterations bound the IK and RRT): the datagen graph's timeout_plan, so a loaded
    # machine cuts neither path's searches (2.0 did: the 300-attempt cluster run differed from serial)
    plan_timeout: float = 10.0
    images: bool = False  # record 84x84 front and wrist RGB in observations
    image_size: int = 84
    camera_width: int = 0  # perception camera (estimate mode / cloud collisions); 0 x 0: the task's camera_size
    camera_height: int = 0  # (128x128; Threading 480x360), as params/sim_driver.yaml's front camera, and the
    # datagen graph's depth noise, so the graph and this env
    depth_noise: float = 0.001  # estimate from the same clouds
    video: bool = True  # front view for the run's MP4 (160x120 unless perception renders it; only while capturing)
    # fraction of the Panda's V/A/J limits for planned motions (= graphs.yaml's planner): at full speed
    # the tracked transit strays from its plan into pegs and the table more often (docs/results_log.md, "Before the faithful tasks")
    velocity_scale: float = 0.7
    seed: int = 0
    contact_model: str = DEFAULT_CONTACT_MODEL  # sim/contact_model.py; its source demos must be made on it

    def __post_init__(self):
        if self.perception not in PERCEPTION_MODES:
            raise InvalidInputError(f"perception must be one of {PERCEPTION_MODES}, got {self.perception!r}",
                                    reason="INVALID_PARAMETER")
        if self.collision not in COLLISION_SOURCES:
            raise InvalidInputError(f"collision must be one of {COLLISION_SOURCES}, got {self.collision!r}",
                                    reason="INVALID_PARAMETER")
        contact_settings(self.contact_model)  # INVALID_PARAMETER for an unknown name
        if not 0.0 < self.velocity_scale <= 1.0:
            raise InvalidInputError(f"velocity_scale must be in (0, 1], got {self.velocity_scale}",
                                    reason="INVALID_PARAMETER")


class SimGenerationEnv:
    """GenerationEnv (see attempt.GenerationEnv) over one in-process SimWorld."""

    def __init__(self, config: SimEnvConfig = SimEnvConfig(), world: SimWorld | None = None):
        self.cfg = config
        cams = []
        if config.perception == "estimate" or config.collision == "cloud" or config.images:
            cams.append(CameraConfig("front", config.camera_width, config.camera_height,
                                     noise_base=config.depth_noise))
        if config.images:
            cams.append(CameraConfig("wrist", config.image_size, config.image_size))
        if config.video and not any(c.name == "front" for c in cams):
            cams.append(CameraConfig("front", 160, 120))
        self.world = world or SimWorld(cameras=tuple(cams), **contact_settings(config.contact_model))
        self.kin = PandaKinematics()
        self.cm = CollisionModel(self.kin)
        self.planner = MotionPlanner(self.kin, IKSolver(self.kin, rng=np.random.default_rng(config.seed)), self.cm,
                                     velocity_scale=config.velocity_scale, seed=config.seed)
        self.planner.warm_up()
        self.scene = None
        self.grasps = GraspTracker()
        self._last_gripper, self._closing = -1.0, -1
        self._estimates: dict[str, Pose] = {}
        self.last_estimate: tuple[int, dict] | None = None  # (sensor stamp ns, what perception returned)
        self._collided = False
        self._models = None
        self._last_attached: str | None = None
        self._last_support: str | None = None
        self._last_skill_object: str | None = None  # the object of a skill that started from a transit
        self._next_skill = 0  # the skill whose pose estimate comes next (set_next_skill)

    # -- GenerationEnv
    def reset(self, task: str, variant: str, seed: int):
        self.scene = self.world.reset(task, variant, seed)
        self._estimates = {}
        self._beliefs = LookBeliefs(get_task(task))
        self.last_estimate = None
        self.grasps.clear()
        self._last_gripper, self._closing = -1.0, -1
        self._last_attached = self._last_support = self._last_skill_object = None
        self._collided = False
        self._models = None
        self._next_skill = 0
        self.planner.reseed(seed)  # the attempt's plans depend on (reset seed, plan index) only
        return self.scene

    def observe(self) -> Observation:
        w = self.world
        images = {}
        if self.cfg.images:
            images = {"front": _resize(w.render("front").rgb, self.cfg.image_size),
                      "wrist": w.render("wrist").rgb}
        q = w.joint_positions()
        ee = Pose.from_matrix(self.kin.fk(q))  # FK of the joints, as the graph sees the EE (1e-8 m from pybullet's)
        objects = dict(self._estimates)
        held = self.grasps.holding()
        if held in objects:  # a held object moves with the hand (rigid attachment)
            objects[held] = self.grasps.pose_now(held, ee.matrix())
        return Observation(ee_pose=ee, gripper=w.finger_positions(), joint_positions=q,
                           object_poses=objects, images=images, ee_wrench=w.ee_wrench(),
                           true_object_poses=w.object_poses(), stamp_ns=_ns(w.time), object_joints=w.object_joints())

    def estimate_poses(self) -> dict[str, Pose]:
        if self.cfg.perception == "ground_truth":
            self._estimates = self.world.object_poses()
            self.last_estimate = (_ns(self.world.time), dict(self._estimates))
            return dict(self._estimates)
        from ..perception.fixtures import estimate_with_fixtures
        from ..perception.models import models_for_objects
        from ..perception.pipeline import PerceptionStatus

        if self._models is None:
            self._models = models_for_objects([o for o in self.scene.objects if o.id != "obstacle"])
        frame = self.world.render("front")
        required = self._required_ids()
        res = estimate_with_fixtures(frame.valid_points(), self._models, {o.id: o for o in self.scene.objects},
                                     camera_position=frame.T_world_camera[:3, 3], object_ids=required,
                                     joints=self.world.object_joints(), known=self._estimates)
        held = self.grasps.holding()
        seen = {k: v.pose for k, v in res.poses.items() if k != held}
        # as the graph path: an object missed now keeps its belief; one never seen fails the estimate, and
        # so does a look that failed as a whole (no table, an empty cloud)
        if not res.ok and (res.status is not PerceptionStatus.OBJECT_MISSING
                           or unaccounted(required, seen, self._estimates)):
            raise SkillGenError(f"perception: {res.status.name}: {res.message}", reason="PERCEPTION_FAILED")
        self._estimates.update(self._beliefs.update(seen, {k: v.confidence for k, v in res.poses.items()},
                                                    self._estimates, self._next_skill))
        self.last_estimate = (_ns(self.world.time), seen)
        self._obstacle_cloud = res.obstacles
        return dict(self._estimates)

    def _required_ids(self) -> list[str]:
        """Objects perception must find now: not the held one, nor one still hidden (TaskSpec.required_ids)."""
        return get_task(self.scene.task).required_ids([o.id for o in self.scene.objects], self._next_skill,
                                                      self.grasps.holding())

    def current_ee_pose(self) -> Pose:
        return self.world.ee_pose()

    def current_q(self) -> np.ndarray:
        return self.world.joint_positions()

    def _planning_scene(self, skill_object: str | None, attached: str | None):
        poses = dict(self.world.object_poses()) if self.cfg.perception == "ground_truth" else dict(self._estimates)
        if self.cfg.collision == "cloud":
            # The cloud is the obstacle; boxes at the perceived poses only say which points belong
            # to the manipulated object (allowed contacts), as in the planner node.
            frame = self.world.render("front")
            boxes = [b for o in self.scene.objects if o.id in poses and o.id != attached
                     for b in object_boxes(o, poses[o.id], self.world.object_joints())]
            self.cm.set_boxes(boxes, as_obstacles=False)
            att = self._attachment(attached, poses)
            self.cm.set_point_cloud(frame.valid_points(), self_filter_q=self.world.joint_positions(), attached=att,
                                    fill_below=True, views=[DepthView(frame.depth, frame.K, frame.T_world_camera)])
            return att
        boxes = []
        for o in self.scene.objects:
            if o.id == attached:
                continue
            pose = poses.get(o.id)
            if o.id == "obstacle" and self.cfg.perception != "ground_truth":
                pose = self.scene.poses[o.id]  # scene geometry mode: the fixture map is known
            if pose is None:  # not seen yet (hidden in the closed drawer): no box, and no true pose leaked
                continue
            boxes += object_boxes(o, pose, self.world.object_joints())  # the sim's joint state, as the driver's topic
        self.cm.set_boxes(boxes)
        self.cm.set_point_cloud(np.empty((0, 3)))
        return self._attachment(attached, poses)

    def _support_of(self, attached: str | None) -> str:
        """What the held object rests on as the transfer starts (a drawer's tray under Coffee Prep's pod), as
        the planner node finds it: the part right below the object's believed pose, else the table."""
        poses = dict(self.world.object_poses()) if self.cfg.perception == "ground_truth" else dict(self._estimates)
        if attached not in poses:
            return "table"
        boxes = [b for o in self.scene.objects if o.id != attached and o.id in poses
                 for b in object_boxes(o, poses[o.id], self.world.object_joints())]
        return support_below(boxes, poses[attached].position) or "table"

    def _attachment(self, attached: str | None, poses) -> AttachedObject | None:
        if not attached:
            return None
        obj = next(o for o in self.scene.objects if o.id == attached)
        T_ee_obj = self.grasps.object_in_ee(attached)
        if T_ee_obj is None:  # not seen closing on it: assume it sits where perception last saw it
            if attached not in poses:
                return None
            T_ee_obj = np.linalg.inv(self.world.ee_pose().matrix()) @ poses[attached].matrix()
        return attached_from_parts(obj, T_ee_obj)

    def plan_and_execute(self, target: Pose, mode: str, attached: str | None):
        skill_object = self._next_object
        att = self._planning_scene(skill_object, attached if mode == "transfer" else None)
        # Transit after a place: the hand may still touch what it just released (retreat only); after a
        # skill that held nothing (a drawer opened by its handle), the object that skill worked on, as the
        # planner node's "object whose box holds the start EE" (nodes/planner.py)
        released = (self._last_attached or self._last_skill_object) if mode == "transit" else None
        released_support = self._last_support if mode == "transit" else None
        movable = tuple(o.id for o in self.scene.objects if not o.is_fixture)  # the paper's retreat/approach rule
        res = self.planner.plan(self.world.joint_positions(), target, Mode(mode), attached=att,
                                manipulated=skill_object if mode == "transit" else None, released=released,
                                released_support=released_support,
                                start_support=self._support_of(attached) if mode == "transfer" else "table",
                                goal_support=skill_object,
                                timeout=self.cfg.plan_timeout, extras=self._planner_extras, movable=movable)
        self._last_attached = attached if mode == "transfer" else None
        self._last_support = skill_object if mode == "transfer" else None
        self._last_skill_object = skill_object if mode == "transit" else None
        self.last_plan = res
        if res.status is not PlanStatus.SUCCESS:
            return res.status.name, []
        tr = res.trajectory
        observations = []
        others = [o.id for o in self.scene.objects if o.id not in (skill_object, attached)]
        # The planner lets the hand touch what it just released, that object's support and every
        # manipulated object on the retreat and the approach (the paper ignores these contacts there):
        # so does the execution check, while the EE is still within the retreat's length (10 cm when
        # it backed out from a fixture) of where it started, or within the approach's of the target.
        w = self.world
        near = max(self.planner.retreat_distance, res.retreat_length) + 0.01
        near_goal = self.planner.approach_distance + 0.01
        start_ee = w.ee_pose().position
        on_retreat = [x for x in (released, released_support, *movable) if x]
        w.start_trajectory([f"panda_joint{i}" for i in range(1, 8)], tr.times, tr.positions, tr.velocities)
        while True:
            _, _, done = w.step_trajectory()
            check = others
            ee = w.ee_pose().position
            if on_retreat and np.linalg.norm(ee - start_ee) < near:
                check = [o for o in others if o not in on_retreat]
            elif np.linalg.norm(ee - target.position) < near_goal:
                check = [o for o in others if o not in movable]
            if check and w.robot_in_collision_with(check):
                self._collided = True
            observations.append(self.observe())
            if done is not None:
                break
        return ("SUCCESS" if done.code.name == "SUCCESSFUL" else "EXECUTION_FAILED"), observations

    def step(self, target: Pose, gripper: float) -> Observation:
        self.world.step(target, gripper)
        self._track_grasp(float(gripper))
        return self.observe()

    def _track_grasp(self, gripper: float) -> None:
        """Rigid attachment from the command stream: a few periods after the hand closes on the
        skill's object, remember it in the EE frame (GraspTracker); opening releases it."""
        if gripper > 0 >= self._last_gripper:
            self._closing = CLOSE_PERIODS
        elif gripper <= 0 < self._last_gripper:  # believed where the hand let go, until perception looks again
            self._estimates.update(self.grasps.released(self.world.ee_pose().matrix()))
            self._closing = -1
        self._last_gripper = gripper
        if self._closing > 0:
            self._closing -= 1
            if self._closing == 0 and carriable(self.scene.task, self._next_object):
                poses = self.world.object_poses() if self.cfg.perception == "ground_truth" else self._estimates
                if self._next_object in poses:
                    self.grasps.grasped(self._next_object, poses[self._next_object].matrix(),
                                        self.world.ee_pose().matrix())

    def task_success(self) -> bool:
        return self.world.task_success()

    def collided(self) -> bool:
        c, self._collided = self._collided, False
        return c

    # The attempt tells the env which object the next skill manipulates (for allowed contacts).
    _next_object: str | None = None
    _planner_extras = True

    def set_planner_extras(self, on: bool) -> None:
        """The attempt's profile (profile.py): the planner's start repairs on or off."""
        self._planner_extras = bool(on)

    def set_skill_object(self, object_id: str | None) -> None:
        self._next_object = object_id

    def set_next_skill(self, skill_index: int) -> None:
        """The attempt's next skill: which objects its pose estimate requires (TaskSpec.hidden_until)."""
        self._next_skill = int(skill_index)

    @property
    def next_skill(self) -> int:
        """The skill the next pose estimate is for (diagnostics attribute each look to it)."""
        return self._next_skill

    def model_symmetry(self, object_id: str):
        """The symmetry perception assumes for `object_id` (none before its first estimate or unknown)."""
        m = (self._models or {}).get(object_id)
        return m.symmetry if m is not None else "none"

    def close(self) -> None:
        self.world.close()


def _ns(t: float) -> int:
    return int(round(t * 1e9))


def _resize(rgb: np.ndarray, size: int) -> np.ndarray:
    import cv2

    return cv2.resize(np.asarray(rgb, np.uint8), (size, size), interpolation=cv2.INTER_AREA)

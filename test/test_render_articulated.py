"""The video re-render (core/dataset/render.py) shows an articulated object's joints as recorded: Coffee's lid
where obs/coffee_machine_joints put it at each frame, not at its reset value."""
from __future__ import annotations

import numpy as np

from skillgen_ros.core.dataset.render import EpisodeRenderer
from skillgen_ros.core.generation.episode import EpisodeRecorder, Observation, StepLabel
from skillgen_ros.core.tasks import coffee as C


def test_the_rerendered_lid_follows_the_recorded_angle():
    r = EpisodeRenderer()
    try:
        scene = r.world.reset("Coffee", "D0", 0)
        rec = EpisodeRecorder("ground_truth")
        truth = {k: v.as_array() for k, v in scene.poses.items()}
        for angle in np.linspace(C.LID_OPEN, 0.0, 5):   # the lid swinging shut over five steps
            o = Observation(ee_pose=r.world.ee_pose(), gripper=r.world.finger_positions(),
                            joint_positions=r.world.joint_positions(), object_poses=truth, true_object_poses=truth,
                            object_joints={"coffee_machine/lid": float(angle)})
            rec.add(o, np.zeros(7), o.ee_pose, -1.0, StepLabel(True, 1, 0, np.array([0, 0, 0, 0, 0, 0, 1.0])))
        episode = rec.episode(False)
        frames, _ = r.render("Coffee", "D0", 0, episode)
        assert len(frames) >= 2
        assert r.world.object_joints()["coffee_machine/lid"] == 0.0     # the last frame: shut, as recorded
        open_again = r.render("Coffee", "D0", 0, rec.episode(False).__class__(
            **{**episode.__dict__, "obs": {k: v for k, v in episode.obs.items() if not k.endswith("_joints")}}))
        assert open_again[0] and r.world.object_joints()["coffee_machine/lid"] == C.LID_OPEN   # nothing recorded
    finally:
        r.close()

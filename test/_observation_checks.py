"""Checks on a recorded episode's held object, shared by the in-process and graph tests (issue 25,
item 7): while the gripper carries it, its recorded pose moves with the hand; once released, it
stays where the hand let it go (no jump back to where it lay before the grasp)."""
import numpy as np
from scipy.spatial.transform import Rotation


def held_object_errors(obs: dict, actions_abs: np.ndarray, object_id: str, lift: float = 0.01) -> dict:
    """{"carry": max drift (m) of the object's position in the EE frame over the carried steps,
    "carried_steps": how many, "release_jump": the largest step-to-step move after the release (m),
    "release_drift_xy": how far (m, in x-y) it ended from where it was let go}."""
    pos, ee_p, ee_q = obs[f"{object_id}_pose"][:, :3], obs["robot0_eef_pos"], obs["robot0_eef_quat"]
    closed = actions_abs[:, 7] > 0
    lifted = pos[:, 2] > pos[0, 2] + lift
    carried = np.flatnonzero(closed & lifted)
    in_ee = Rotation.from_quat(ee_q[carried]).inv().apply(pos[carried] - ee_p[carried])
    out = {"carried_steps": len(carried), "carry": float(np.ptp(in_ee, axis=0).max()) if len(carried) else np.nan}
    opened = np.flatnonzero(~closed[1:] & closed[:-1]) + 1  # first step of each release
    if len(opened):
        k = opened[-1]
        out["release_jump"] = float(np.linalg.norm(np.diff(pos[k:], axis=0), axis=1).max(initial=0.0))
        out["release_drift_xy"] = float(np.linalg.norm(pos[-1, :2] - pos[k, :2]))
    return out

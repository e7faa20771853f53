"""datagen's reader of the driver's state_history (nodes/state_history.DriverHistory) on hand-built
answers: each period's true poses and articulated joint values keep their layout and their stamp;
looking up the joints right after the poses of the same steps reuses that answer; a robot without
the service has no joint values, not an error; missing periods fail with a reason."""
import numpy as np
import pytest

from skillgen_ros import rosenv  # noqa: F401

from skillgen_interfaces.srv import StateHistory
from skillgen_ros.core.errors import SkillGenError
from skillgen_ros.nodes.state_history import DriverHistory, ns, to_time

LID = "coffee_machine/lid"
STAMPS = [1_000_000_000, 1_050_000_000, 1_100_000_000]
ANGLES = [2.09, 1.5, 0.01]


class _Client:
    def __init__(self, ready=True):
        self.ready = ready

    def service_is_ready(self):
        return self.ready

    def wait_for_service(self, timeout_sec):
        return self.ready


def _answer(req, joints=True, kinds=None):
    """Three periods of a Coffee scene, as the driver answers (req.after, req.until]."""
    keep = [i for i, t in enumerate(STAMPS) if t > ns(req.after) and (not ns(req.until) or t <= ns(req.until))]
    r = StateHistory.Response(success=True, reason_code="OK")
    r.stamps = [to_time(STAMPS[i]) for i in keep]
    r.kinds = [(kinds or [StateHistory.Response.TRAJECTORY] * 3)[i] for i in keep]
    r.joint_positions = [float(i) for i in keep for _ in range(7)]
    r.finger_positions = [0.04 - 0.01 * i for i in keep for _ in range(2)]
    r.object_ids = ["coffee_machine", "coffee_pod"]
    r.object_poses = [float(v) for i in keep for k in range(2) for v in (i, k, 0, 0, 0, 0, 1)]
    if joints:
        r.joint_names = [LID]
        r.object_joints = [ANGLES[i] for i in keep]
    return r


def _history(ready=True, **kw):
    asked = []

    def call(_client, req):
        asked.append((ns(req.after), ns(req.until)))
        return _answer(req, **kw)
    return DriverHistory(_Client(ready), call), asked


def test_joint_values_come_per_period_with_the_true_poses_in_one_call():
    h, asked = _history()
    truth = h.true_object_poses(STAMPS[1:])
    joints = h.object_joints(STAMPS[1:])
    assert len(asked) == 1, asked  # the joints of the steps just resolved: the same answer
    assert joints == {STAMPS[1]: {LID: ANGLES[1]}, STAMPS[2]: {LID: ANGLES[2]}}
    np.testing.assert_array_equal(truth[STAMPS[2]]["coffee_pod"], [2, 1, 0, 0, 0, 0, 1])
    assert h.object_joints(STAMPS[:1]) == {STAMPS[0]: {LID: ANGLES[0]}} and len(asked) == 2  # another span
    assert h.object_joints([]) == {} and len(asked) == 2


def test_motion_and_skill_periods_carry_the_joint_values():
    h, _ = _history(kinds=[StateHistory.Response.OSC_TARGET, StateHistory.Response.TRAJECTORY,
                           StateHistory.Response.TRAJECTORY])
    rows = h.trajectory_periods(STAMPS[0] - 1)
    assert [r[0] for r in rows] == STAMPS[1:] and [r[4] for r in rows] == [{LID: a} for a in ANGLES[1:]]
    skill = h.skill_periods(STAMPS)
    assert skill["object_joints"] == [{LID: a} for a in ANGLES]
    np.testing.assert_allclose(skill["fingers"][:, 0], [0.04, 0.03, 0.02])


def test_a_scene_without_joints_and_a_robot_without_history():
    h, _ = _history(joints=False)  # Square: every period has joint values, none of them
    assert h.object_joints(STAMPS) == {t: {} for t in STAMPS}
    assert h.skill_periods(STAMPS)["object_joints"] == [{}, {}, {}]
    real, asked = _history(ready=False)  # a real robot's driver: no service, no joint values, no call
    assert real.object_joints(STAMPS) == {} and asked == []


def test_periods_the_driver_no_longer_has_fail_with_a_reason():
    h, _ = _history()
    with pytest.raises(SkillGenError) as e:
        h.object_joints([STAMPS[0], STAMPS[2] + 1])
    assert e.value.reason == "TIMEOUT"

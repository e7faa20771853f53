"""Generated requests for every service and action of every node (issue 19), shared by
test/test_fuzz.py (a few examples each, in the suite) and bench/reliability/run.py (many).

Each Interface has a hypothesis strategy for its request (NaN/inf and huge floats, out-of-range
integers within the field's type, unknown/empty/long/odd names, oversized arrays), a `call` that
sends one request into a running graph and returns the answer (None = no answer within the
timeout, a hang), and `problem(answer)`, which says what is wrong with an answer ('' = fine: a
result or a reason code). The graph is helpers/boundary_graphs.yaml's.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Callable

from hypothesis import strategies as st

from skillgen_interfaces.action import ExecuteTrajectory, Generate, Gripper, ReplaySkill, RunTask
from skillgen_interfaces.msg import SceneObject
from skillgen_interfaces.srv import (EstimatePoses, LoadDemos, PlanToPose, Recorder, ResetScene, RunAttempt,
                                     StateHistory, TaskSuccess)

U8, U32, U64 = (0, 255), (0, 2**32 - 1), (0, 2**64 - 1)
I32, I64 = (-2**31, 2**31 - 1), (-2**63, 2**63 - 1)
SPECIAL = [0.0, -0.0, -1.0, 1.0, 1e-300, 1e300, -1e300, float("nan"), float("inf"), float("-inf")]
CALL_TIMEOUT = 60.0  # seconds before an unanswered request counts as a hang
# execute_trajectory may legitimately run its longest accepted goal (60 s of motion; in lockstep with
# the mock's cameras slower than real time) and answers the next goal after it: its own budget.
ACTION_TIMEOUT = {"execute_trajectory": 240.0}


def floats() -> st.SearchStrategy:
    return st.one_of(st.sampled_from(SPECIAL), st.floats(allow_nan=True, allow_infinity=True),
                     st.floats(-2.0, 2.0))


def ints(lo_hi) -> st.SearchStrategy:
    lo, hi = lo_hi
    return st.one_of(st.sampled_from([lo, hi, 0, 1]), st.integers(lo, hi))


def names(*good: str) -> st.SearchStrategy:
    return st.one_of(st.sampled_from([*good, "", "Nope", "x" * 300, "a/b", "../../etc"]), st.text(max_size=24))


def float_list(max_size: int = 12) -> st.SearchStrategy:
    return st.one_of(st.lists(floats(), max_size=max_size), st.just([0.0] * 20_000))


def _set(msg, fields: dict):
    for k, v in fields.items():
        setattr(msg, k, v)
    return msg


@st.composite
def poses(draw):
    from geometry_msgs.msg import Pose

    p = Pose()
    p.position.x, p.position.y, p.position.z = (draw(floats()) for _ in range(3))
    q = draw(st.one_of(st.just((0.0, 0.0, 0.0, 1.0)), st.just((1.0, 0.0, 0.0, 0.0)), st.tuples(*[floats()] * 4)))
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = (float(v) for v in q)
    return p


@st.composite
def scene_objects(draw):
    o = SceneObject(id=draw(names("box", "square_nut")), type=draw(names("box")), has_pose=draw(st.booleans()),
                    pose=draw(poses()), is_fixture=draw(st.booleans()))
    o.half_extents = draw(st.lists(floats(), max_size=4))
    return o


@st.composite
def plan_requests(draw):
    from geometry_msgs.msg import PoseStamped

    t = PoseStamped(pose=draw(poses()))
    t.header.frame_id = draw(st.sampled_from(["world", "", "map", "panda_link0"]))
    return _set(PlanToPose.Request(), dict(
        target=t, mode=draw(ints(U8)), attached_object=draw(names("box")), collision_source=draw(ints(U8)),
        timeout=draw(floats()), execute=False, start_positions=draw(float_list(9)),
        objects=draw(st.lists(scene_objects(), max_size=3)), manipulated_object=draw(names("box")),
        seeded=draw(st.booleans()), seed=draw(ints(U64)), plan_index=draw(ints(U32)), extras=draw(st.booleans())))


@st.composite
def stamps(draw):
    from builtin_interfaces.msg import Time

    return Time(sec=draw(ints(I32)), nanosec=draw(ints(U32)))


@st.composite
def trajectories(draw):
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    tr = JointTrajectory(joint_names=draw(st.one_of(st.just([f"panda_joint{i}" for i in range(1, 8)]),
                                                    st.lists(names("panda_joint1"), max_size=8))))
    for _ in range(draw(st.integers(0, 4))):
        pt = JointTrajectoryPoint(positions=draw(float_list(8)), velocities=draw(st.lists(floats(), max_size=8)))
        pt.time_from_start.sec, pt.time_from_start.nanosec = draw(ints(I32)), draw(ints(U32))
        tr.points.append(pt)
    return tr


def _generate_fields(draw) -> dict:
    return dict(task=draw(names("Square", "PickPlace")), variant=draw(names("D0", "D1")),
                method=draw(names("skillgen", "mimicgen")), augment=draw(st.booleans()),
                augment_translation=draw(floats()), augment_rotation_deg=draw(floats()), seed=draw(ints(U64)),
                source_demos=draw(st.sampled_from(["", "/nonexistent", "x" * 5000])),
                selection=draw(names("random", "nearest")), output_dir=draw(names("fuzz_out", "/etc/x", "/tmp")),
                profile=draw(names("paper", "skillgen_ros")))


@st.composite
def generate_goals(draw):
    return _set(Generate.Goal(), dict(
        _generate_fields(draw), attempts=draw(ints(U32)), target_successes=draw(ints(U32)),
        first_index=draw(ints(U32)), record_bag=False, record_first=draw(ints(U32)), record_count=draw(ints(U32)),
        video_attempts=draw(ints(I32)), initiation_candidates=draw(ints(I32))))


@st.composite
def run_attempt_requests(draw):
    return _set(RunAttempt.Request(), dict(_generate_fields(draw), index=draw(ints(U32))))


@st.composite
def replay_goals(draw):
    return _set(ReplaySkill.Goal(), dict(
        skill_index=draw(ints(U32)), source_demo=draw(ints(I32)),
        source_demos=draw(st.sampled_from(["", "/nonexistent", "y" * 5000])), task=draw(names("Square")),
        selection=draw(names("random", "nearest")), object_pose=draw(poses()), action_noise=draw(floats()),
        recovery=draw(st.booleans()), seed=draw(ints(U64))))


@st.composite
def recorder_starts(draw):
    return Recorder.Request(output=draw(names("fuzz_bag", "/etc/bag", "/tmp")),
                            topics=draw(st.one_of(st.lists(names("joint_states", "/osc_target", "bad topic!"),
                                                           max_size=4), st.just(["t"] * 5000))))


@st.composite
def run_task_goals(draw):
    return RunTask.Goal(task=draw(names("Square")), checkpoint=draw(st.sampled_from(["", "/nonexistent.pt", "z" * 5000])),
                        initiation_mode=draw(names("class", "reg", "tamp", "bc")), max_steps=draw(ints(U32)),
                        variant=draw(names("D0")), seed=draw(ints(I64)))


def _reason_problem(reason: str) -> str:
    if not reason:
        return "answered without a reason code"
    return "INTERNAL_ERROR (an exception in the node)" if reason == "INTERNAL_ERROR" else ""


def _goal_problem(answer) -> str:
    accepted, result = answer
    if accepted is None:
        return "goal never answered"
    if accepted is False:
        return ""  # rejected at once (e.g. an empty task is the readiness probe): an answer
    if result is None:
        return "accepted, but no result within the timeout"
    return _reason_problem(getattr(result, "reason", "") or ("OK" if getattr(result, "success", False) else ""))


@dataclass(frozen=True)
class Interface:
    name: str
    kind: str                     # "service" | "action"
    type: object
    ros_name: str
    strategy: st.SearchStrategy
    problem: Callable[[object], str]
    valid: Callable[[], object]   # a request this node must still serve afterwards
    valid_ok: Callable[[object], bool]
    namespace: str = ""           # "/iso": datagen alone
    probe: Callable[[], object] | None = None


def _srv(reason_field: str) -> Callable[[object], str]:
    return lambda r: "no answer within the timeout" if r is None else _reason_problem(getattr(r, reason_field))


def _recorder_problem(r) -> str:
    if r is None:
        return "no answer within the timeout"
    return "" if r.success or re.match(r"^[A-Z][A-Z_]+: ", r.message) else f"no reason code: {r.message!r}"


def _plan_valid():
    import numpy as np
    from geometry_msgs.msg import PoseStamped
    from scipy.spatial.transform import Rotation

    from skillgen_ros.core.planning.kinematics import PandaKinematics
    from skillgen_ros.core.robot import Q_HOME

    T = PandaKinematics().fk(np.asarray(Q_HOME))
    t = PoseStamped()
    t.header.frame_id = "world"
    t.pose.position.x, t.pose.position.y, t.pose.position.z = float(T[0, 3]) + 0.05, float(T[1, 3]), float(T[2, 3])
    (t.pose.orientation.x, t.pose.orientation.y, t.pose.orientation.z,
     t.pose.orientation.w) = (float(v) for v in Rotation.from_matrix(T[:3, :3]).as_quat())
    return PlanToPose.Request(target=t, timeout=5.0, start_positions=list(Q_HOME), seeded=True, seed=1)


INTERFACES: dict[str, Interface] = {i.name: i for i in [
    Interface("plan_to_pose", "service", PlanToPose, "plan_to_pose", plan_requests(),
              lambda r: "no answer within the timeout" if r is None else (
                  "internal error" if r.message.startswith("internal error") else _reason_problem(r.status_name)),
              _plan_valid, lambda r: r.status_name == "SUCCESS"),
    Interface("estimate_poses", "service", EstimatePoses, "estimate_poses",
              st.builds(EstimatePoses.Request, object_ids=st.one_of(st.lists(names("square_nut", "square_peg"),
                                                                             max_size=4), st.just(["o"] * 5000)),
                        newer_than=stamps()),
              _srv("status_name"), EstimatePoses.Request, lambda r: r.status_name in ("OK", "NO_DATA")),
    Interface("reset_scene", "service", ResetScene, "reset_scene",
              st.builds(ResetScene.Request, task=names("Square", "Threading"), variant=names("D0", "D1"),
                        seed=ints(I64)),
              _srv("reason_code"), lambda: ResetScene.Request(task="Square", variant="D0", seed=1),
              lambda r: r.success),
    Interface("state_history", "service", StateHistory, "state_history",
              st.builds(StateHistory.Request, after=stamps(), until=stamps()),
              lambda r: "no answer within the timeout" if r is None else (
                  "" if r.success or r.reason_code else "answered without a reason code"),
              StateHistory.Request, lambda r: r.success or bool(r.reason_code)),
    Interface("task_success", "service", TaskSuccess, "task_success", st.just(TaskSuccess.Request()),
              lambda r: "" if r is not None else "no answer within the timeout", TaskSuccess.Request,
              lambda r: r is not None),
    Interface("execute_trajectory", "action", ExecuteTrajectory, "execute_trajectory",
              st.builds(ExecuteTrajectory.Goal, trajectory=trajectories(), goal_tolerance=floats()),
              lambda a: "goal never answered" if a[0] is None else (
                  "" if a[0] is False or (a[1] is not None and (a[1].error_code == 0 or a[1].error_string))
                  else "no result or no error string"),
              ExecuteTrajectory.Goal, lambda a: a[0] is not None,
              probe=ExecuteTrajectory.Goal),  # empty: refused at once, safe to repeat until answered
    Interface("gripper_command", "action", Gripper, "gripper_command",
              st.builds(Gripper.Goal, position=floats(), max_effort=floats()),
              lambda a: "goal never answered" if a[0] is None else ("" if a[0] is False or a[1] is not None
                                                                    else "accepted, but no result"),
              lambda: Gripper.Goal(position=0.04, max_effort=10.0), lambda a: a[1] is not None,
              probe=lambda: Gripper.Goal(position=float("nan"))),  # refused at once (INVALID_GOAL)
    Interface("replay_skill", "action", ReplaySkill, "replay_skill", replay_goals(), _goal_problem,
              lambda: LoadDemos.Request(task="Square"), lambda r: r.success, probe=ReplaySkill.Goal),
    Interface("load_demos", "service", LoadDemos, "skill_replay/load_demos",
              st.builds(LoadDemos.Request, task=names("Square"),
                        source_demos=st.sampled_from(["", "/nonexistent", "w" * 5000])),
              _srv("reason_code"), lambda: LoadDemos.Request(task="Square"), lambda r: r.success),
    Interface("recorder_start", "service", Recorder, "recorder/start", recorder_starts(), _recorder_problem,
              Recorder.Request, lambda r: r is not None),
    Interface("recorder_stop", "service", Recorder, "recorder/stop", recorder_starts(), _recorder_problem,
              Recorder.Request, lambda r: r is not None),
    Interface("recorder_pause", "service", Recorder, "recorder/pause", recorder_starts(), _recorder_problem,
              Recorder.Request, lambda r: r is not None),
    Interface("recorder_resume", "service", Recorder, "recorder/resume", recorder_starts(), _recorder_problem,
              Recorder.Request, lambda r: r is not None),
    Interface("run_task", "action", RunTask, "run_task", run_task_goals(), _goal_problem,
              lambda: RunTask.Goal(task="Square", checkpoint="/nonexistent.pt"),
              lambda a: a[1] is not None and a[1].reason == "BAD_CHECKPOINT", probe=RunTask.Goal),
    Interface("generate", "action", Generate, "generate", generate_goals(), _goal_problem,
              lambda: Generate.Goal(task="Square", variant="D0", method="skillgen", attempts=1,
                                    augment_translation=-1.0, augment_rotation_deg=-1.0),
              lambda a: a[1] is not None and a[1].reason in ("GRAPH_NOT_READY", "OUTPUT_EXISTS"),
              namespace="/iso", probe=Generate.Goal),
    Interface("run_attempt", "service", RunAttempt, "run_attempt", run_attempt_requests(), _srv("reason"),
              lambda: RunAttempt.Request(task="Nope"), lambda r: r.reason == "UNKNOWN_TASK", namespace="/iso"),
]}


def call(calls_by_ns: dict, iface: Interface, request):
    """One request through the right Calls object; the answer as `problem` expects it."""
    calls = calls_by_ns[iface.namespace]
    if iface.kind == "service":
        return calls.service(iface.type, iface.ros_name, request, timeout=CALL_TIMEOUT)
    probe = iface.probe() if iface.probe is not None else None
    return calls.goal(iface.type, iface.ros_name, request, timeout=ACTION_TIMEOUT.get(iface.name, CALL_TIMEOUT),
                      probe=probe)


def still_serves(calls_by_ns: dict, iface: Interface) -> bool:
    """The node answers a valid request afterwards (replay_skill: its node's load_demos)."""
    valid = iface.valid()
    if iface.name == "replay_skill":
        return iface.valid_ok(calls_by_ns[""].service(LoadDemos, "skill_replay/load_demos", valid,
                                                      timeout=CALL_TIMEOUT))
    answer = call(calls_by_ns, iface, valid)
    if iface.name == "recorder_start" and answer is not None and answer.success:
        calls_by_ns[""].service(Recorder, "recorder/stop", Recorder.Request(), timeout=CALL_TIMEOUT)
    return answer is not None and iface.valid_ok(answer)

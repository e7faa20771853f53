"""Validation at every boundary (issue 19): each service and action of each node answers bad input
(NaN/inf, out of range, empty or unknown names, oversized arrays, paths outside what the node may
write) with a reason code, logs no traceback, and still serves a valid request afterwards.

One graph serves the module (helpers/boundary_graphs.yaml: mock driver, planner, perception,
skill_replay, recorder, hsp), plus datagen alone in a namespace of its own, where a valid request
is answered GRAPH_NOT_READY after 3 x timeout_state. Core checks: test_validation.py.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from geometry_msgs.msg import Pose, PoseStamped
from skillgen_interfaces.action import Generate, ReplaySkill, RunTask
from skillgen_interfaces.msg import SceneObject
from skillgen_interfaces.srv import EstimatePoses, LoadDemos, PlanToPose, Recorder, ResetScene, RunAttempt

from conftest import next_domain_id
from helpers.ros_calls import boundary_graphs
from skillgen_ros.core.robot import Q_HOME

NAN, INF = float("nan"), float("inf")


@pytest.fixture(scope="module")
def nodes(tmp_path_factory):
    """(Calls into the boundaries graph, Calls into the lone datagen, both graphs, artifacts dir)."""
    art = tmp_path_factory.mktemp("boundaries")
    with boundary_graphs(next_domain_id(), art) as (calls, graphs):
        yield calls[""], calls["/iso"], graphs, art


def _no_tracebacks(graphs) -> None:
    for g in graphs:
        g.check_alive()
        assert "Traceback" not in g.output(), g.output()[-3000:]


def _pose(x=0.5, y=0.0, z=0.3, q=(1.0, 0.0, 0.0, 0.0)) -> Pose:
    p = Pose()
    p.position.x, p.position.y, p.position.z = float(x), float(y), float(z)
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = (float(v) for v in q)
    return p


def _reachable() -> Pose:
    """5 cm in front of the home EE pose: a target the planner reaches."""
    from scipy.spatial.transform import Rotation

    from skillgen_ros.core.planning.kinematics import PandaKinematics

    T = PandaKinematics().fk(np.asarray(Q_HOME))
    return _pose(T[0, 3] + 0.05, T[1, 3], T[2, 3], tuple(Rotation.from_matrix(T[:3, :3]).as_quat()))


def _plan(**kw) -> PlanToPose.Request:
    r = PlanToPose.Request(target=PoseStamped(pose=_reachable()), mode=PlanToPose.Request.TRANSIT,
                           collision_source=PlanToPose.Request.SOURCE_SCENE, timeout=5.0,
                           start_positions=list(Q_HOME), seeded=True, seed=1)
    r.target.header.frame_id = "world"
    for k, v in kw.items():
        setattr(r, k, v)
    return r


def _box(oid="box", half=(0.02, 0.02, 0.02), **kw) -> SceneObject:
    o = SceneObject(id=oid, type="box", has_pose=True, pose=_pose(0.6, 0.3, 0.02, (0.0, 0.0, 0.0, 1.0)))
    o.half_extents = list(half)
    for k, v in kw.items():
        setattr(o, k, v)
    return o


def _target(**p) -> PoseStamped:
    t = PoseStamped(pose=_pose(**p))
    t.header.frame_id = "world"
    return t


BAD_PLANS = {
    "NaN target": dict(target=_target(x=NAN)),
    "inf target": dict(target=_target(z=INF)),
    "far target": dict(target=_target(x=1e6)),
    "zero quaternion": dict(target=_target(q=(0.0, 0.0, 0.0, 0.0))),
    "NaN timeout": dict(timeout=NAN),
    "inf timeout": dict(timeout=INF),
    "huge timeout": dict(timeout=1e9),
    "6 joints": dict(start_positions=list(Q_HOME[:6])),
    "NaN joint": dict(start_positions=[NAN] + list(Q_HOME[1:])),
    "joint past its limit": dict(start_positions=[10.0] + list(Q_HOME[1:])),
    "oversized start": dict(start_positions=[0.0] * 100_000),
    "unknown mode": dict(mode=7),
    "unknown collision source": dict(collision_source=9),
    "NaN half extents": dict(objects=[_box(half=(NAN, 0.02, 0.02))]),
    "negative half extents": dict(objects=[_box(half=(-0.1, 0.02, 0.02))]),
    "empty object id": dict(objects=[_box(oid="")]),
    "duplicate object id": dict(objects=[_box(), _box()]),
    "too many objects": dict(objects=[_box(oid=f"b{i}") for i in range(600)]),
    "unknown attached object": dict(mode=PlanToPose.Request.TRANSFER, attached_object="ghost", objects=[_box()]),
    "unknown manipulated object": dict(manipulated_object="ghost", objects=[_box()]),
    "long name": dict(manipulated_object="x" * 5000),
}


def test_plan_to_pose_rejects_bad_requests_and_keeps_planning(nodes):
    calls, _, graphs, _ = nodes
    for case, kw in BAD_PLANS.items():
        r = calls.service(PlanToPose, "plan_to_pose", _plan(**kw), probe=_plan(mode=7))
        assert r is not None and r.status_name == "INVALID_REQUEST", (case, r and r.message)
        assert "internal error" not in r.message, (case, r.message)
    ok = calls.service(PlanToPose, "plan_to_pose", _plan())
    assert ok.status_name == "SUCCESS", ok.message
    _no_tracebacks(graphs)


def test_estimate_poses_rejects_bad_ids_and_keeps_answering(nodes):
    calls, _, graphs, _ = nodes
    for case, ids in {"unknown": ["ghost"], "empty": [""], "oversized": [f"o{i}" for i in range(5000)],
                      "long": ["y" * 5000]}.items():
        r = calls.service(EstimatePoses, "estimate_poses", EstimatePoses.Request(object_ids=ids))
        assert r is not None and r.status_name == "OBJECT_MISSING", (case, r and r.message)
    r = calls.service(EstimatePoses, "estimate_poses", EstimatePoses.Request())
    assert r.status_name in ("OK", "NO_DATA"), r.message  # ground_truth mode: answered either way
    _no_tracebacks(graphs)


def test_reset_scene_rejects_bad_requests_and_keeps_resetting(nodes):
    calls, _, graphs, _ = nodes
    for (task, variant, seed), reason in {
            ("", "D0", 0): "UNKNOWN_TASK", ("Nope", "D0", 0): "UNKNOWN_TASK", ("Z" * 5000, "D0", 0): "UNKNOWN_TASK",
            ("Square", "D9", 0): "UNKNOWN_VARIANT", ("Square", "", 0): "UNKNOWN_VARIANT",
            ("Square", "D0", -1): "INVALID_SEED", ("Square", "D0", 2**40): "INVALID_SEED"}.items():
        r = calls.service(ResetScene, "reset_scene", ResetScene.Request(task=task, variant=variant, seed=seed))
        assert r is not None and not r.success and r.reason_code == reason, (task[:10], variant, seed, r and r.message)
    r = calls.service(ResetScene, "reset_scene", ResetScene.Request(task="Square", variant="D0", seed=3))
    assert r.success and r.reason_code == "OK" and len(r.objects) >= 2
    _no_tracebacks(graphs)


def _replay(**kw) -> ReplaySkill.Goal:
    g = ReplaySkill.Goal(task="Square", skill_index=0, source_demo=-1, object_pose=_pose(0.1, 0.1, 0.0, (0, 0, 0, 1)),
                         action_noise=-1.0)
    for k, v in kw.items():
        setattr(g, k, v)
    return g


def test_replay_skill_and_load_demos_reject_bad_requests_and_keep_serving(nodes):
    calls, _, graphs, _ = nodes
    for case, (kw, reason) in {
            "unknown task": (dict(task="Nope"), "UNKNOWN_TASK"),
            "NaN noise": (dict(action_noise=NAN), "INVALID_PARAMETER"),
            "inf noise": (dict(action_noise=INF), "INVALID_PARAMETER"),
            "huge noise": (dict(action_noise=50.0), "INVALID_PARAMETER"),
            "NaN pose": (dict(object_pose=_pose(x=NAN)), "INVALID_INPUT"),
            "far pose": (dict(object_pose=_pose(x=1e7, q=(0, 0, 0, 1))), "INVALID_POSE"),
            "bad demo index": (dict(source_demo=99), "BAD_DEMO_INDEX"),
            "no demos there": (dict(source_demos="/nonexistent/dir"), "BAG_NOT_FOUND"),
            "unknown selection": (dict(selection="bogus"), None),
            "long selection": (dict(selection="s" * 5000), "INVALID_NAME")}.items():
        accepted, res = calls.goal(ReplaySkill, "replay_skill", _replay(**kw), probe=ReplaySkill.Goal(),
                                   repeat=True)  # refused at once: harmless to resend under load
        assert accepted and res is not None and not res.success, case
        assert res.reason and res.reason != "INTERNAL_ERROR" and (reason is None or res.reason == reason), \
            (case, res.reason, res.message)
    for task, reason in {"": "INVALID_NAME", "Nope": "UNKNOWN_TASK"}.items():
        r = calls.service(LoadDemos, "skill_replay/load_demos", LoadDemos.Request(task=task))
        assert not r.success and r.reason_code == reason, (task, r.message)
    r = calls.service(LoadDemos, "skill_replay/load_demos", LoadDemos.Request(task="Square"))
    assert r.success and r.demos == 10, r.message
    _no_tracebacks(graphs)


def test_recorder_refuses_paths_outside_its_roots_and_bad_topics(nodes, tmp_path):
    calls, _, graphs, _ = nodes
    for case, (req, reason) in {
            "system dir": (Recorder.Request(output="/etc/skillgen_bag"), "OUTPUT_OUTSIDE_ROOTS"),
            "escape": (Recorder.Request(output="../" * 30 + "root/skillgen_bag"), "OUTPUT_OUTSIDE_ROOTS"),
            "home dir": (Recorder.Request(output="~/skillgen_bag"), "OUTPUT_OUTSIDE_ROOTS"),
            "bad topic": (Recorder.Request(output=str(tmp_path / "b1"), topics=["not a topic!"]), "INVALID_TOPIC"),
            "too many topics": (Recorder.Request(output=str(tmp_path / "b2"), topics=[f"t{i}" for i in range(5000)]),
                                "INVALID_TOPIC")}.items():
        r = calls.service(Recorder, "recorder/start", req)
        assert r is not None and not r.success, case
        assert reason is None or r.message.startswith(reason + ":"), (case, r.message)
    for srv in ("stop", "pause", "resume"):
        r = calls.service(Recorder, f"recorder/{srv}", Recorder.Request())
        assert not r.success and r.message.split(":")[0] in ("NOT_RECORDING", "BAD_STATE"), (srv, r.message)
    r = calls.service(Recorder, "recorder/start", Recorder.Request(output=str(tmp_path / "ok")))
    assert r.success, r.message
    busy = calls.service(Recorder, "recorder/start", Recorder.Request(output=str(tmp_path / "ok2")))
    assert not busy.success and busy.message.startswith("BUSY:")
    assert calls.service(Recorder, "recorder/stop", Recorder.Request()).success
    again = calls.service(Recorder, "recorder/start", Recorder.Request(output=str(tmp_path / "ok")))
    assert not again.success and "BAG_EXISTS" in again.message  # never overwrites a bag
    _no_tracebacks(graphs)


def test_run_task_rejects_bad_goals_with_reasons(nodes, tmp_path):
    calls, _, graphs, _ = nodes
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"not a checkpoint")
    for case, (kw, reason) in {
            "unknown task": (dict(task="Nope", checkpoint=str(junk)), "UNKNOWN_TASK"),
            "no checkpoint": (dict(task="Square", checkpoint=""), "BAD_CHECKPOINT"),
            "missing checkpoint": (dict(task="Square", checkpoint="/nonexistent.pt"), "BAD_CHECKPOINT"),
            "junk checkpoint": (dict(task="Square", checkpoint=str(junk)), "BAD_CHECKPOINT"),
            "huge max_steps": (dict(task="Square", checkpoint=str(junk), max_steps=10**9), "INVALID_PARAMETER"),
            "long variant": (dict(task="Square", checkpoint=str(junk), variant="v" * 5000), "INVALID_NAME")}.items():
        accepted, res = calls.goal(RunTask, "run_task", RunTask.Goal(**kw), probe=RunTask.Goal(),
                                   repeat=True)  # refused at once: harmless to resend under load
        assert accepted and res is not None and not res.success, case
        assert res.reason == reason, (case, res.reason, res.message)
    _no_tracebacks(graphs)


def _generate(**kw) -> Generate.Goal:
    g = Generate.Goal(task="Square", variant="D0", method="skillgen", attempts=1, seed=0,
                      augment_translation=-1.0, augment_rotation_deg=-1.0)
    for k, v in kw.items():
        setattr(g, k, v)
    return g


BAD_GOALS = {
    "NaN translation (issue 19)": (dict(augment=True, augment_translation=NAN), "INVALID_PARAMETER"),
    "inf translation": (dict(augment=True, augment_translation=INF), "INVALID_PARAMETER"),
    "translation too large": (dict(augment=True, augment_translation=5.0), "INVALID_PARAMETER"),
    "NaN rotation": (dict(augment_rotation_deg=NAN), "INVALID_PARAMETER"),
    "rotation past 180": (dict(augment_rotation_deg=200.0), "INVALID_PARAMETER"),
    "unknown task": (dict(task="Nope"), "UNKNOWN_TASK"),
    "long task": (dict(task="T" * 5000), "INVALID_NAME"),
    "unknown method": (dict(method="nope"), "UNKNOWN_METHOD"),
    "zero attempts": (dict(attempts=0), "INVALID_ATTEMPTS"),
    "absurd attempts": (dict(attempts=4_000_000_000), "INVALID_ATTEMPTS"),
    "seed past numpy's range": (dict(seed=2**40), "INVALID_SEED"),
    "output in /etc": (dict(output_dir="/etc/skillgen_run"), "OUTPUT_OUTSIDE_ROOTS"),
    "output escaping with ..": (dict(output_dir="../" * 30 + "root/run"), "OUTPUT_OUTSIDE_ROOTS"),
    "video_attempts < -1": (dict(video_attempts=-5), "INVALID_PARAMETER"),
    "unknown profile": (dict(profile="bogus"), None),
    "unknown selection": (dict(selection="bogus"), None),
}


def test_generate_and_run_attempt_reject_bad_goals_and_keep_serving(nodes, tmp_path):
    _, iso, graphs, _ = nodes
    for case, (kw, reason) in BAD_GOALS.items():
        accepted, res = iso.goal(Generate, "generate", _generate(**kw), probe=Generate.Goal(task=""), repeat=True)
        assert accepted and res is not None, case
        assert not res.accepted and res.reason and res.reason != "INTERNAL_ERROR", (case, res.reason, res.message)
        assert reason is None or res.reason == reason, (case, res.reason, res.message)
        fields = RunAttempt.Request.get_fields_and_field_types()
        req = RunAttempt.Request(**{**dict(task="Square", variant="D0", method="skillgen", augment_translation=-1.0,
                                           augment_rotation_deg=-1.0), **{k: v for k, v in kw.items() if k in fields}})
        r = iso.service(RunAttempt, "run_attempt", req, repeat=True)
        assert r is not None and not r.accepted and r.reason != "INTERNAL_ERROR", (case, r and r.message)
        if reason is not None and all(k in fields for k in kw):  # RunAttempt has no attempts/video_attempts
            assert r.reason == reason, (case, r.reason, r.message)
    # a valid goal is answered: datagen alone cannot reach a driver, so GRAPH_NOT_READY, not a hang
    accepted, res = iso.goal(Generate, "generate", _generate(output_dir=str(tmp_path / "run")), timeout=120)
    assert accepted and res.reason == "GRAPH_NOT_READY", (res.reason, res.message)
    _no_tracebacks(graphs)


def test_zero_augmentation_stays_zero_and_negative_means_the_default():
    """0.0 is not silently replaced by 0.08 any more (issue 19); -1 (USE_DEFAULT) selects it."""
    import rclpy

    from skillgen_ros.core.skills.augmentation import AugmentationConfig
    from skillgen_ros.nodes.datagen import DatagenNode

    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=next_domain_id())
    try:
        # only _request is used: no executor spins, nothing is served
        node = DatagenNode.__new__(DatagenNode)
        rclpy.node.Node.__init__(node, "datagen_unit", context=ctx)
        node.declare_parameter("output_root", "out")
        node.declare_parameter("action_noise", 0.05)
        node._writable, node._release, node._observation_source, node._profile = ["out"], None, "ground_truth", "paper"
        zero = node._request(_generate(augment=True, augment_translation=0.0, augment_rotation_deg=0.0))
        assert (zero.augment_translation, zero.augment_rotation_deg) == (0.0, 0.0)
        dflt = node._request(_generate(augment=True))
        assert (dflt.augment_translation, dflt.augment_rotation_deg) == (AugmentationConfig().translation,
                                                                        AugmentationConfig().rotation_deg)
        assert not math.isnan(dflt.augment_translation)
        node.destroy_node()
    finally:
        rclpy.shutdown(context=ctx)


@pytest.mark.parametrize("exe,param", [
    ("planner", "velocity_scale:=.nan"), ("planner", "dt:=.inf"), ("perception", "voxel:=.nan"),
    ("perception", "max_cloud_age:=-1.0"), ("skill_replay", "action_noise:=.nan"), ("recorder", "max_chunk_age:=.nan"),
    ("mock_driver", "control_hz:=.inf"), ("datagen", "timeout_plan:=.nan"), ("datagen", "action_noise:=-0.5"),
])
def test_a_bad_parameter_stops_the_node_with_a_reason(exe, param, ros_domain):
    """NaN/inf/out-of-range node parameters are refused at start-up: exit 2, INVALID_PARAMETER naming
    the parameter, no traceback (NaN once passed `not x > 0`-style checks written as `x <= 0`)."""
    import subprocess
    import sys

    from conftest import REPO, node_env

    r = subprocess.run([sys.executable, "-m", "skillgen_ros.cli.main", "run", exe, "--ros-args", "-p", param,
                        "-p", "autostart:=false"] if exe == "recorder" else
                       [sys.executable, "-m", "skillgen_ros.cli.main", "run", exe, "--ros-args", "-p", param],
                       env=node_env(ros_domain), capture_output=True, text=True, timeout=120, cwd=REPO)
    out = r.stdout + r.stderr
    assert r.returncode == 2 and "INVALID_PARAMETER" in out and param.split(":=")[0] in out, out[-2000:]
    assert "Traceback" not in out

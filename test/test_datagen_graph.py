"""End to end over the ROS graph on the simulated Panda (never the mock driver):
sim_driver (lockstep) + skill_replay in one container, perception (estimate), planner, datagen, driven through
the `generate` action with SkillGenClient. One graph serves the module's tests.
"""
import json
import shutil
import signal
from pathlib import Path

import h5py
import numpy as np
import pytest

from _foxglove_checks import decode_all, tf_parents, unconnected
from conftest import REPO, NodeProcess, client_node, next_domain_id, wait_for
from skillgen_ros.answered import first_answer
from skillgen_ros.client import SkillGenClient
from skillgen_ros.core.dataset.hdf5 import validate_dataset
from skillgen_ros.core.generation.outcome import FailureReason
from skillgen_ros.core.viz.robot_tf import panda_tf
from skillgen_ros.graphs import load_graph

# As graphs.yaml's datagen graph: sim_driver and skill_replay composed in one `container` process
# (node-targeted -p), the driver rendering frames on demand (camera_hz 0), with graphs.yaml's depth noise,
# lockstep timeout and planner timing, so an attempt here is the in-process env's attempt.
CONTROL_LOOP = ["sim_driver", "skill_replay", "--ros-args",
                "--params-file", str(REPO / "params" / "sim_driver.yaml"),
                "--params-file", str(REPO / "params" / "skill_replay.yaml"),
                "-p", "sim_driver:cameras:=[front]", "-p", "sim_driver:camera_hz:=0.0",
                "-p", "sim_driver:depth_noise_base:=0.001", "-p", "sim_driver:lockstep_timeout_s:=120.0"]
NODES = {
    "perception": [],
    "planner": ["-p", "velocity_scale:=0.7", "-p", "dt:=0.01"],  # graphs.yaml's: the in-process env's timing
    # perception keeps params/datagen.yaml's timeout (8 s was too short for Coffee Prep's first look, 4 objects and
    # 2 fixtures, at load 4)
    "datagen": ["-p", "timeout_plan:=8.0"],
    "recorder": [a for k, v in next(n for n in load_graph("datagen") if n.exe == "recorder").parameters
                 for a in ("-p", f"{k}:={v}")],  # graphs.yaml's: the scene for Foxglove, the cloud at 1 Hz
}


def _start(exe: str, dom: int) -> NodeProcess:
    return NodeProcess(exe, dom, ["--ros-args", "--params-file", str(REPO / "params" / f"{exe}.yaml"), *NODES[exe]])


@pytest.fixture(scope="module")
def graph():
    dom = next_domain_id()
    procs = {"control_loop": NodeProcess("container", dom, CONTROL_LOOP)}
    procs.update({exe: _start(exe, dom) for exe in NODES})
    client = SkillGenClient(domain_id=dom)
    try:
        assert client.wait_for_server(180), "datagen did not come up (or never answered a probe goal)"
        yield dom, procs, client
    finally:
        client.close()
        for p in procs.values():
            p.stop()


def _run(client, timeout=600, **goal):
    fields = dict(task="Square", variant="D0", method="skillgen", attempts=1, seed=0)
    fields.update(goal)
    assert client.generate(timeout=120, **fields)  # generous: the graph may still be warming up on a busy machine
    return client.result(timeout=timeout)


def test_bad_requests_are_rejected_with_a_reason(graph, tmp_path):
    _, procs, client = graph
    existing = tmp_path / "existing"
    existing.mkdir()
    (existing / "demo.hdf5").write_bytes(b"keep me")
    unannotated = tmp_path / "unannotated" / "demo_00"
    shutil.copytree(REPO / "bags" / "Square" / "demo_00", unannotated)
    (unannotated / "annotations.yaml").unlink()
    cases = [
        (dict(task="NoSuchTask"), "UNKNOWN_TASK"),
        (dict(method="teleport"), "UNKNOWN_METHOD"),
        (dict(attempts=0), "INVALID_ATTEMPTS"),
        (dict(initiation_candidates=-2), "INVALID_PARAMETER"),
        (dict(profile="fastest"), "UNKNOWN_PROFILE"),
        (dict(profile="paper", initiation_candidates=6), "INVALID_PARAMETER"),  # the paper tries one pose
        (dict(output_dir="/proc/skillgen_cannot_write_here"), "OUTPUT_OUTSIDE_ROOTS"),  # not datagen's to write
        (dict(output_dir=str(tmp_path / "a_file" / "out")), "UNWRITABLE_OUTPUT"),  # allowed, but cannot be made
        (dict(output_dir=str(existing)), "OUTPUT_EXISTS"),
        (dict(source_demos=str(tmp_path / "empty")), "NO_SOURCE_DEMOS"),
        (dict(source_demos=str(unannotated.parent)), None),  # some annotation error, named
    ]
    (tmp_path / "empty").mkdir()
    (tmp_path / "a_file").write_text("a file, not a directory")
    for k, (goal, reason) in enumerate(cases):
        goal.setdefault("output_dir", str(tmp_path / f"out{k}"))
        res = _run(client, timeout=60, **goal)
        assert not res.accepted, goal
        if reason:
            assert res.reason == reason, (goal, res.reason, res.message)
        else:
            assert "ANNOTATION" in res.reason and "demo_00" in res.message, (res.reason, res.message)
    assert (existing / "demo.hdf5").read_bytes() == b"keep me"
    assert all(p.proc.poll() is None for p in procs.values()), "a node died on bad input"


def _driver_camera_hz(dom: int) -> float:
    from rclpy.parameter_client import AsyncParameterClient

    with client_node(dom, "camera_hz_probe") as (node, ex):
        cli = AsyncParameterClient(node, "sim_driver")
        assert cli.wait_for_services(timeout_sec=30)
        fut = cli.get_parameters(["camera_hz"])
        ex.spin_until_future_complete(fut, timeout_sec=30)
        return fut.result().values[0].double_value


def test_seeded_attempts_produce_a_valid_robomimic_dataset(graph, tmp_path):
    dom, _, client = graph
    out = tmp_path / "run"
    res = _run(client, attempts=3, output_dir=str(out), record_bag=True, record_first=1, record_count=1)
    assert res.accepted and res.reason == "OK", res.message
    # the session bag holds attempt 1 only, and a third-party reader opens it
    from rosbags.highlevel import AnyReader

    with AnyReader([Path(res.bag_path)]) as r:
        n = sum(1 for _ in r.messages(connections=[c for c in r.connections if c.topic == "/osc_target"]))
    assert 0 < n < 450, n  # one attempt's skill steps, not three
    got = _check_session_bag(Path(res.bag_path))
    # the window's own attempt index, published after the recorder resumed (it once went out while paused)
    assert [m.data for m in got["/run/attempt"]] == [1]
    assert (out / "attempts.mp4").stat().st_size > 0 and (out / "report.html").exists()
    assert 'href="bag"' in (out / "report.html").read_text() and list((out / "clips").glob("attempt_*.mp4"))
    assert _driver_camera_hz(dom) == 0.0, "datagen must put the driver's camera rate back after filming"
    assert res.attempts == 3 and res.successes >= 1, [(f.reason, f.count) for f in res.failures]
    summary = validate_dataset(res.dataset_path)
    assert summary.num_demos == res.successes
    with h5py.File(res.dataset_path, "r") as f:
        assert "env_args" in f["data"].attrs and f["data"].attrs["total"] > 0
        gen = json.loads(f["data"].attrs["env_args"])["generation"]  # no goal profile: the node's parameter
        assert gen["profile"] == "skillgen_ros" and gen["planner_extras"] is True and gen["initiation_candidates"] == 6
        demo = f["data"][sorted(f["data"].keys())[0]]
        for key in ("obs/robot0_eef_pos", "obs/robot0_eef_quat", "obs/robot0_gripper_qpos", "obs/robot0_joint_pos",
                    "obs/square_nut_pose", "obs/square_peg_pose", "actions", "actions_abs", "states", "rewards",
                    "dones", "labels/mp_step", "labels/skill_index", "labels/source_demo",
                    "labels/initiation_target", "labels/augmented"):
            assert key in demo, key
        n = demo.attrs["num_samples"]
        assert demo["actions"].shape == (n, 7) and demo["labels/mp_step"][:].any() and not demo["labels/mp_step"][:].all()
        assert "successful" in f["mask"]
    assert Path(res.report_path).exists()


def _check_session_bag(bag: Path) -> dict:
    """What Foxglove's 3D panel needs, decoded by third-party readers: every link, object, camera
    and planner goal frame connects to world; the robot model, object models, run state and a few clouds.
    Returns the decoded messages by topic."""
    got = decode_all(bag)
    for topic in ("/tf", "/tf_static", "/robot_description", "/scene/object_markers", "/planner/path_markers",
                  "/camera/front/points", "/run/stage", "/run/skill", "/run/attempt"):
        assert got.get(topic), (topic, sorted(got))
    parents = tf_parents(got)
    frames = set(panda_tf().links) | {"square_nut", "square_peg", "square_nut_estimate", "camera_front_optical",
                                      "planner_goal_0"}
    assert frames <= set(parents) and unconnected(set(parents), parents) == [], sorted(parents)
    assert {m.header.frame_id for m in got["/scene/object_markers"][-1].markers[1:]} == {"square_nut", "square_peg"}
    assert {m.data for m in got["/run/stage"]} >= {"motion", "skill"}
    return got


def _one_recorded_attempt(graph, out: Path, task: str, objects: tuple[str, ...]) -> dict:
    """One paper-profile attempt of `task` through the graph (estimated poses, success not required) is
    recorded (demo.hdf5 or failed.hdf5) with each object's pose and the HSP labels of the task's skills;
    returns its arrays (_attempt_arrays)."""
    from skillgen_ros.core.tasks import get_task

    _, procs, client = graph
    res = _run(client, task=task, attempts=1, seed=0, profile="paper", output_dir=str(out))
    assert res.accepted and res.reason == "OK", res.message
    assert res.attempts == 1
    path = res.dataset_path if res.successes else res.failed_path
    with h5py.File(path, "r") as f:
        demo = f["data"][sorted(f["data"].keys())[0]]
        for key in (*(f"obs/{o}_pose" for o in objects), "labels/mp_step", "labels/skill_index", "actions"):
            assert key in demo, key
        assert set(np.unique(demo["labels/skill_index"][:])) - {-1} <= set(range(len(get_task(task).skills)))
    assert all(p.proc.poll() is None for p in procs.values())
    return _attempt_arrays(out)


def test_a_three_piece_assembly_attempt_runs_through_the_graph(graph, tmp_path):
    """The 4-skill task with three free objects."""
    _one_recorded_attempt(graph, tmp_path / "tpa", "ThreePieceAssembly", ("base", "piece_1", "piece_2"))


def test_a_coffee_prep_attempt_runs_through_the_graph(graph, tmp_path):
    """The 5-skill task: the pod hidden in the closed drawer until skill 3, two articulated fixtures whose joint
    values the dataset records at every step."""
    g = _one_recorded_attempt(graph, tmp_path / "cprep", "CoffeePreparation",
                              ("mug", "coffee_machine", "drawer", "coffee_pod"))
    for joints in ("obs/coffee_machine_joints", "obs/drawer_joints"):
        assert g[joints].shape[0] == len(g["actions"]) and np.isfinite(g[joints]).all(), joints


def test_a_coffee_attempt_runs_through_the_graph(graph, tmp_path):
    """The articulated task: the planner takes the machine's lid as an obstacle at the driver's
    object_joint_states value, and the dataset records the lid angle at every step (obs/coffee_machine_joints,
    from the driver's state_history) as the in-process env does: same keys and layout, the lid open after
    the reset in both, and shut when the attempt succeeds."""
    from skillgen_ros.core.generation.attempt import run_attempt
    from skillgen_ros.core.generation.session import RunRequest
    from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv
    from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos
    from skillgen_ros.core.tasks import coffee as C, get_task

    g = _one_recorded_attempt(graph, tmp_path / "coffee", "Coffee", ("coffee_machine", "coffee_pod"))
    lid = g["obs/coffee_machine_joints"]
    assert lid.shape == (len(g["actions"]), 1) and np.isfinite(lid).all()
    assert lid[0, 0] == pytest.approx(C.LID_OPEN, abs=1e-3)  # open after the reset (coffee.py _reset_internal)
    if g["success"]:  # success needs the lid shut: the record saw it close
        assert lid[:, 0].min() < C.LID_CLOSED_TOLERANCE, lid[-5:, 0]

    task = get_task("Coffee")
    env = SimGenerationEnv(SimEnvConfig(perception="estimate", video=False))
    try:
        ep = run_attempt(env, load_source_demos(expand_bag_paths([str(REPO / "bags" / "Coffee")]), task), task,
                         "skillgen", 0, 0, RunRequest(task="Coffee", variant="D0", profile="paper").config()).episode
    finally:
        env.close()
    assert {f"obs/{k}" for k in ep.obs} == {k for k in g if k.startswith("obs/")}  # the same keys, lid included
    assert ep.obs["coffee_machine_joints"].shape[1:] == lid.shape[1:]
    # the values are not compared across the two paths here: in a full suite run the graph's first Coffee
    # observation came one settling period after the in-process one (the pod 0.4 mm away; alone they
    # matched within 1e-6 for 54 steps). test_graph_records_the_true_object_poses_the_in_process_env_records
    # compares the two paths' values on Square.
    lid_inproc = ep.obs["coffee_machine_joints"][:, 0]
    assert lid_inproc[0] == pytest.approx(lid[0, 0], abs=1e-6)  # both record the lid open after the reset


def test_skill_replay_loads_demos_ahead_and_says_why_not(graph, tmp_path):
    from skillgen_interfaces.srv import LoadDemos

    dom, _, _ = graph
    with client_node(dom, "load_demos_client") as (node, ex):
        cli = node.create_client(LoadDemos, "skill_replay/load_demos")
        assert cli.wait_for_service(timeout_sec=30)

        def call(**kw):  # loading is idempotent: resend if an answer is lost to discovery
            return first_answer(lambda: cli.call_async(LoadDemos.Request(**kw)),
                                lambda f, s: ex.spin_until_future_complete(f, timeout_sec=s), timeout=60, each=20)

        ok = call(task="Square")
        assert ok.success and ok.demos > 0, ok.message
        empty = call(task="Square", source_demos=str(tmp_path))
        assert not empty.success and empty.reason_code == "NO_SOURCE_DEMOS", empty.message
        unknown = call(task="Nope", source_demos=str(REPO / "bags" / "Square"))
        assert not unknown.success and unknown.reason_code == "UNKNOWN_TASK", unknown.reason_code


def _generation_args(out: Path) -> dict:
    import json

    path = out / ("demo.hdf5" if (out / "demo.hdf5").exists() else "failed.hdf5")
    with h5py.File(path, "r") as f:
        return json.loads(f["data"].attrs["env_args"])["generation"]


def test_no_video_attempts_means_no_mp4_and_a_goal_picks_the_paper_profile(graph, tmp_path):
    _, _, client = graph
    out = tmp_path / "novideo"
    res = _run(client, attempts=1, output_dir=str(out), video_attempts=0, profile="paper")
    assert res.accepted and res.attempts == 1, res.message
    assert not (out / "attempts.mp4").exists()
    gen = _generation_args(out)  # the goal's profile, applied over the graph (PlanToPose.extras false)
    assert gen["profile"] == "paper" and gen["initiation_candidates"] == 1
    assert gen["planner_extras"] is False and gen["release_moves"] is False and gen["check_collisions"] is False


def test_a_bad_profile_parameter_stops_datagen_with_a_reason(start_node):
    proc = start_node("datagen", "--ros-args", "-p", "profile:=fastest")
    assert proc.proc.wait(timeout=120) == 2
    out = proc.stop()
    assert "INVALID_PARAMETER" in out and "unknown profile" in out


def test_killed_perception_fails_attempts_with_a_reason_and_the_run_goes_on(graph, tmp_path):
    dom, procs, client = graph
    out = tmp_path / "killed"
    assert client.generate(task="Square", variant="D0", method="skillgen", attempts=4, seed=7, output_dir=str(out))
    assert wait_for(lambda: client.feedback() is not None and client.feedback().attempts >= 1, 300)
    procs["perception"].proc.send_signal(signal.SIGKILL)
    procs["perception"].proc.wait(10)
    # observable, not a sleep: an attempt has failed for want of perception (feedback's last_reason)
    assert wait_for(lambda: client.feedback() is not None and client.feedback().last_reason == "PERCEPTION_FAILED",
                    600)
    procs["perception"] = _start("perception", dom)
    res = client.result(timeout=900)
    assert res.accepted and res.attempts == 4, res.message
    failures = {f.reason: f.count for f in res.failures}
    assert failures.get("PERCEPTION_FAILED", 0) >= 1, failures
    summary = validate_dataset(res.dataset_path)
    assert summary.num_demos == res.successes


def test_run_attempt_service_runs_one_attempt(graph, tmp_path):
    from skillgen_interfaces.srv import RunAttempt

    dom, _, _ = graph
    with client_node(dom, "run_attempt_client") as (node, ex):
        cli = node.create_client(RunAttempt, "run_attempt")
        assert cli.wait_for_service(timeout_sec=30)
        bad = first_answer(lambda: cli.call_async(RunAttempt.Request(task="Square", variant="D0", method="nope", index=0,
                                                                     output_dir=str(tmp_path / "bad"))),
                           lambda f, s: ex.spin_until_future_complete(f, timeout_sec=s), timeout=30)
        assert bad is not None and not bad.accepted and bad.reason == "UNKNOWN_METHOD"
        fut = cli.call_async(RunAttempt.Request(task="Square", variant="D0", method="skillgen", seed=0, index=2,
                                                output_dir=str(tmp_path / "one")))
        ex.spin_until_future_complete(fut, timeout_sec=300)
        r = fut.result()
        assert r.accepted and r.seconds > 0, r
        assert r.reason in {x.value for x in FailureReason} and (r.reason == "OK") == r.success, r
        assert (tmp_path / "one" / "demo.hdf5").exists()


def _attempt_arrays(out: Path) -> dict:
    for name in ("demo.hdf5", "failed.hdf5"):
        with h5py.File(out / name, "r") as f:
            for d in f["data"].values():
                return {**{f"obs/{k}": v[()] for k, v in d["obs"].items()}, "actions": d["actions"][()],
                        "actions_abs": d["actions_abs"][()], "success": bool(d.attrs["success"]),
                        **{f"estimates/{k}": v[()] for k, v in d["estimates"].items()}}


def test_graph_records_the_true_object_poses_the_in_process_env_records(graph, tmp_path):
    """obs/<id>_pose in graph mode is the sim's pose at every step (the driver's state_history), not
    the estimate frozen at the skill's start: the held nut moves with the hand and stays where it is
    let go. The in-process env, run on the same (seed, index), records the same arrays until the
    fingers touch the nut; after contact the two sims drift apart chaotically from differences at
    the 1e-9 level (the graph's idle lockstep periods, trajectory times in whole nanoseconds)."""
    from _observation_checks import held_object_errors
    from skillgen_ros.core.generation.attempt import GenerationConfig, run_attempt
    from skillgen_ros.core.generation.sim_env import SimEnvConfig, SimGenerationEnv
    from skillgen_ros.core.skills.bag_demos import expand_bag_paths, load_source_demos
    from skillgen_ros.core.tasks import get_task

    _, _, client = graph
    res = _run(client, attempts=1, seed=3, output_dir=str(tmp_path / "g"), video_attempts=0)
    assert res.accepted and res.attempts == 1, res.message
    g = _attempt_arrays(tmp_path / "g")
    assert validate_dataset(res.failed_path).env_args["generation"]["observation_source"] == "ground_truth"
    if g["success"]:
        c = held_object_errors({k[4:]: v for k, v in g.items() if k.startswith("obs/")}, g["actions_abs"], "square_nut")
        assert c["carried_steps"] > 20 and c["carry"] < 0.01, c
        assert c["release_jump"] < 0.05 and c["release_drift_xy"] < 0.03, c  # it settles: cm; the bug: 0.3 m

    task = get_task("Square")
    env = SimGenerationEnv(SimEnvConfig(perception="estimate", video=False))
    try:
        ep = run_attempt(env, load_source_demos(expand_bag_paths([str(REPO / "bags" / "Square")]), task), task,
                         "skillgen", 0, 3, GenerationConfig(variant="D0")).episode
    finally:
        env.close()
    local = {**{f"obs/{k}": v for k, v in ep.obs.items()}, "actions": ep.actions,
             **{f"estimates/{k}": v for k, v in ep.estimates.items()}}
    assert set(local) == set(g) - {"actions_abs", "success"}
    contact = int(np.flatnonzero(ep.actions_abs[:, 7] > 0)[0])  # the first closing command
    assert contact > 30 and len(g["actions"]) > contact
    for k, v in local.items():
        if k.startswith("estimates/"):  # two runs of the same perception on the same scene, until contact;
            # after it the two sims differ by mm (a held nut near the peg changes the peg's estimate)
            before = ep.estimates["step"] <= contact
            np.testing.assert_allclose(g[k][before], v[before], atol=1e-5, err_msg=k)
        else:
            np.testing.assert_allclose(g[k][:contact], v[:contact], atol=1e-4, err_msg=k)

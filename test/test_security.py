"""Security basics (issue 19): no code-executing deserialization anywhere, outputs never overwritten,
and discovery stays loopback-only unless the user chose otherwise."""
from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from skillgen_ros.rosenv import launch_environment

REPO = Path(__file__).resolve().parents[1]
SOURCES = [p for d in ("skillgen_ros", "bench", "scripts", "launch") for p in (REPO / d).rglob("*.py")]


def _calls(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
            owner = getattr(f.value, "id", "") if isinstance(f, ast.Attribute) else ""
            yield owner, name, node


def test_no_pickle_and_no_unsafe_loads_in_the_code():
    assert len(SOURCES) > 50
    bad = []
    for path in SOURCES:
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                mods = [a.name for a in node.names] + [getattr(node, "module", None) or ""]
                if any(m.split(".")[0] in ("pickle", "cPickle", "dill", "joblib", "shelve") for m in mods):
                    bad.append(f"{path}:{node.lineno} imports a pickle module")
        for owner, name, node in _calls(tree):
            kw = {k.arg: k.value for k in node.keywords}
            if owner == "torch" and name == "load" and not (
                    isinstance(kw.get("weights_only"), ast.Constant) and kw["weights_only"].value is True):
                bad.append(f"{path}:{node.lineno} torch.load without weights_only=True")
            if owner in ("np", "numpy") and name == "load" and isinstance(kw.get("allow_pickle"), ast.Constant) \
                    and kw["allow_pickle"].value:
                bad.append(f"{path}:{node.lineno} np.load(allow_pickle=True)")
            if owner == "yaml" and name in ("load", "load_all", "unsafe_load", "full_load"):
                loader = kw.get("Loader")
                if loader is None or "Safe" not in ast.unparse(loader):
                    bad.append(f"{path}:{node.lineno} yaml.{name} without a safe loader")
    assert not bad, "\n".join(bad)


def test_launch_environment_keeps_a_user_choice_and_defaults_to_loopback():
    assert launch_environment({})["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert "ROS_AUTOMATIC_DISCOVERY_RANGE" not in launch_environment({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"})
    assert "OMP_NUM_THREADS" not in launch_environment({"OMP_NUM_THREADS": "4"})
    text = (REPO / "launch" / "skillgen.launch.py").read_text()
    assert "launch_environment(" in text and not re.search(r'"ROS_AUTOMATIC_DISCOVERY_RANGE"\s*:\s*"LOCALHOST"', text)


def test_a_user_set_discovery_range_reaches_the_nodes(tmp_path):
    """`skillgen run` (like the launch file) passes the user's range through, LOCALHOST otherwise."""
    probe = ("import os, sys; sys.argv=['x']; from skillgen_ros import rosenv; "
             "print(rosenv.node_environment(dict(os.environ))['ROS_AUTOMATIC_DISCOVERY_RANGE'])")
    for given, want in (("SUBNET", "SUBNET"), (None, "LOCALHOST")):
        env = {k: v for k, v in os.environ.items() if k != "ROS_AUTOMATIC_DISCOVERY_RANGE"}
        if given:
            env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = given
        out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=60)
        assert out.stdout.strip() == want, out.stderr


def test_reports_and_deploy_results_are_never_overwritten(tmp_path):
    from skillgen_ros.core.dataset.report import write_report
    from skillgen_ros.core.errors import InvalidInputError
    from skillgen_ros.core.generation.session import check_output_dir

    (tmp_path / "report.md").write_text("an earlier run's report\n")
    with pytest.raises(InvalidInputError) as e:
        check_output_dir(str(tmp_path))
    assert e.value.reason == "OUTPUT_EXISTS"
    with pytest.raises(InvalidInputError) as e:
        write_report(str(tmp_path), [object()])
    assert e.value.reason == "OUTPUT_EXISTS"
    assert (tmp_path / "report.md").read_text() == "an earlier run's report\n"
    (tmp_path / "results.json").write_text("{}")
    r = subprocess.run([sys.executable, "-m", "skillgen_ros.cli.main", "deploy", "--checkpoint", "x.pt", "--task",
                        "Square", "--variant", "D0", "--rollouts", "1", "--in-process", "--output", str(tmp_path)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "OUTPUT_EXISTS" in r.stderr and (tmp_path / "results.json").read_text() == "{}"

"""The plugin loads wherever skillgen_ros is installed: its `pytest11` entry point, proven in a
fresh virtual environment.

Why this set-up: the shared venv holds an editable install made before the entry point existed, so
testing there proves nothing. The temp venv (`--without-pip`, so it starts empty) gets a *regular*
`pip install --no-deps --no-build-isolation` of this checkout's package files: a wheel built from
setup.py with its entry_points metadata, exactly what a user's `pip install` produces. Its
dependencies (pytest, rclpy, numpy...) are not installed again (minutes and network); a `.pth`
line makes the shared site-packages importable. That line only appends the directory to sys.path:
the `.pth` files inside it, among them the editable finder of skillgen_ros, are not processed, so
the only importable skillgen_ros is the one in the temp venv (asserted). The inner session does
not pass `-p skillgen_ros.testing`; the fixture is found only if pytest loaded the plugin from the
distribution's entry point, which `pluginmanager.list_plugin_distinfo()` confirms, and
`-p no:skillgen_ros.testing` (the entry point's name) turns it off again. Last, our own conftest
(which names the plugin in `pytest_plugins`) runs there too: loaded twice under one name, it must
neither fail nor warn.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import venv

from conftest import REPO

PACKAGE_FILES = ("setup.py", "setup.cfg", "package.xml", "requirements-extras.txt", "resource", "params", "launch",
                 "skillgen_ros")

INNER_TEST = '''
import os

import skillgen_ros


def test_plugin_from_the_entry_point(ros_domain, request):
    pm = request.config.pluginmanager
    plugin = pm.get_plugin("skillgen_ros.testing")
    dists = {getattr(d, "project_name", None) or d.metadata["name"] for p, d in pm.list_plugin_distinfo() if p is plugin}
    assert dists == {"skillgen_ros"}, dists
    assert plugin.__file__.startswith(os.environ["FRESH_VENV"]), plugin.__file__
    assert skillgen_ros.__file__.startswith(os.environ["FRESH_VENV"]), skillgen_ros.__file__
    assert os.environ["ROS_DOMAIN_ID"] == str(ros_domain)
'''


def test_plugin_loads_from_the_entry_point_in_a_fresh_venv(tmp_path):
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    py = env_dir / "bin" / "python"
    site = subprocess.run([py, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
                          capture_output=True, text=True, check=True).stdout.strip()
    with open(os.path.join(site, "_shared_site_packages.pth"), "w") as f:
        f.write(sysconfig.get_path("purelib") + "\n")  # the shared venv's packages; its .pth files stay off
    src = tmp_path / "src"  # only the package's files: pip builds in-tree and would litter the checkout
    src.mkdir()
    for name in PACKAGE_FILES:
        if (REPO / name).is_dir():
            shutil.copytree(REPO / name, src / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy(REPO / name, src / name)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTEST_ADDOPTS", "PYTEST_PLUGINS")}
    env["FRESH_VENV"] = str(env_dir)
    r = subprocess.run([py, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", "--no-index", str(src)],
                       capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    (tmp_path / "t").mkdir()
    (tmp_path / "t" / "test_ep.py").write_text(INNER_TEST)
    run = [py, "-m", "pytest", "-p", "no:cacheprovider", "-q", "test_ep.py"]
    on = subprocess.run(run, capture_output=True, text=True, env=env, cwd=tmp_path / "t", timeout=120)
    assert on.returncode == 0 and "1 passed" in on.stdout, on.stdout + on.stderr
    off = subprocess.run(run + ["-p", "no:skillgen_ros.testing"], capture_output=True, text=True, env=env,
                         cwd=tmp_path / "t", timeout=120)
    assert off.returncode != 0 and "fixture 'ros_domain' not found" in off.stdout, off.stdout + off.stderr
    assert sys.prefix != str(env_dir)

    # our own conftest (pytest_plugins = ["skillgen_ros.testing"]) where the entry point has already
    # registered the plugin, as after the lead's reinstall: no duplicate registration, no warning
    suite = tmp_path / "suite"
    suite.mkdir()
    for name in ("conftest.py", "test_testing_domains.py"):
        shutil.copy(REPO / "test" / name, suite / name)
    both = subprocess.run([py, "-m", "pytest", "-p", "no:cacheprovider", "-q", "-W", "error::pytest.PytestWarning",
                           "-W", "ignore::pytest.PytestRemovedIn10Warning", str(suite)],
                          capture_output=True, text=True, env=env, cwd=suite, timeout=120)
    assert both.returncode == 0 and "4 passed" in both.stdout, both.stdout + both.stderr

"""Declared dependencies are used (issue 24 removed rich, std_srvs and tmux, which nothing used)."""
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CODE = "\n".join(p.read_text() for d in ("skillgen_ros", "launch", "bench", "scripts")
                 for p in (ROOT / d).rglob("*.py"))


def _imported(module: str) -> bool:
    return re.search(rf"^\s*(from|import) {re.escape(module)}\b", CODE, flags=re.M) is not None


def test_every_ros_package_the_package_xml_names_is_imported():
    deps = re.findall(r"<exec_depend>([\w-]+)</exec_depend>", (ROOT / "package.xml").read_text())
    ros = [d for d in deps if not d.startswith("python3-") and d not in ("rclpy_action", "pinocchio", "ompl")]
    assert "rclpy" in ros and "std_srvs" not in ros
    unused = [d for d in ros if not _imported(d)]
    assert not unused, f"package.xml depends on {unused}, which no module imports"


def test_removed_dependencies_stay_removed():
    req = (ROOT / "requirements.txt").read_text()
    assert not re.search(r"^(rich|ros-jazzy-std-srvs)==", req, flags=re.M)
    assert not _imported("rich") and not _imported("std_srvs")
    assert "tmux" not in (ROOT / "scripts" / "bootstrap.sh").read_text().split("APT_PKGS=(")[1].split(")")[0]

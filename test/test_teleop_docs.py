"""docs/teleop.md's "where to grasp" stays true: its table is the skill-point table, its pictures exist,
and the script that renders them puts every marked point inside the picture."""
from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import numpy as np

from skillgen_ros.core.tasks import TASK_NAMES, get_task
from skillgen_ros.core.tasks.skill_points import skill_point_name, skill_point_offset

ROOT = Path(__file__).resolve().parents[1]
DOC = (ROOT / "docs" / "teleop.md").read_text()


def _script():
    spec = importlib.util.spec_from_file_location("teleop_grasps", ROOT / "scripts" / "teleop_grasps.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_grasp_table_is_the_skill_point_table():
    rows = re.findall(r"^\| (\w+) \| (\d) (\w+) \| (\w+) \| (\w+) \| \(([^)]*)\) \|$", DOC, flags=re.M)
    assert len(rows) == sum(len(get_task(t).skills) for t in TASK_NAMES)
    for task_name, idx, skill_name, obj, point, offset in rows:
        task = get_task(task_name)
        sk = task.skills[int(idx)]
        assert (sk.name, sk.object_id, skill_point_name(task, sk.index)) == (skill_name, obj, point)
        assert np.allclose([float(v) for v in offset.split(",")], skill_point_offset(task, sk.index), atol=6e-4)


def test_every_task_has_its_picture_in_the_docs():
    for t in TASK_NAMES:
        assert f"(teleop_grasps_{t}.png)" in DOC and (ROOT / "docs" / f"teleop_grasps_{t}.png").is_file()
    assert "docs/foxglove/teleop.json" in DOC  # the layout with the wrist camera (test_foxglove_scene checks it)


def test_the_picture_script_marks_every_skill_point_inside_the_image(tmp_path):
    import matplotlib.image as mpimg

    path, rows = _script().render_task("NutAssembly", tmp_path, width=320, height=200)
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[0] > 100
    assert [r["object"] for r in rows] == [sk.object_id for sk in get_task("NutAssembly").skills]
    for r in rows:
        u, v = r["pixel"]
        assert 0 <= u < 320 and 0 <= v < 200, r

"""Reset-region checks shared by the task tests: widths against the paper's appendix."""
from __future__ import annotations

import numpy as np


def assert_widths_match(task, paper: dict) -> None:
    """paper: {(variant, object id): (x width m, y width m, yaw range deg)}, to the millimetre / degree."""
    for (v, oid), (w, h, yaw) in paper.items():
        r = task.regions(v)[oid]
        assert round(r.x[1] - r.x[0], 3) == w and round(r.y[1] - r.y[0], 3) == h, (v, oid, r)
        assert round(np.degrees(r.yaw[1] - r.yaw[0])) == yaw, (v, oid, r)

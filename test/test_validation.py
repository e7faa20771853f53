"""core/validation.py: the checks every node runs at its boundary, and the NaN-safe augmentation."""
from __future__ import annotations

import math
import tempfile
from pathlib import Path

import pytest

from skillgen_ros.core import validation as V
from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.skills.augmentation import AugmentationConfig

NAN, INF = float("nan"), float("inf")


def _reason(fn, *a, **kw) -> str:
    with pytest.raises(InvalidInputError) as e:
        fn(*a, **kw)
    return e.value.reason


def test_finite_refuses_nan_inf_and_out_of_range():
    assert V.finite("x", 0.5, 0.0, 1.0) == 0.5
    for bad in (NAN, INF, -INF, -0.1, 1.1, "abc", None):
        assert _reason(V.finite, "x", bad, 0.0, 1.0) == "INVALID_PARAMETER", bad
    assert _reason(V.finite, "x", 0.0, 0.0, 1.0, lo_open=True) == "INVALID_PARAMETER"
    assert _reason(V.finite, "x", NAN, reason="INVALID_REQUEST") == "INVALID_REQUEST"


def test_or_default_negative_selects_default_zero_stays_zero():
    assert V.or_default("t", V.USE_DEFAULT, 0.08, 0.5) == 0.08
    assert V.or_default("t", -7.0, 0.08, 0.5) == 0.08
    assert V.or_default("t", 0.0, 0.08, 0.5) == 0.0  # issue 19: 0 was silently replaced by 0.08
    for bad in (NAN, INF, -INF, 0.51):
        assert _reason(V.or_default, "t", bad, 0.08, 0.5) == "INVALID_PARAMETER", bad


def test_arrays_names_and_lists():
    assert V.finite_array("q", [1, 2, 3], length=3).tolist() == [1.0, 2.0, 3.0]
    assert _reason(V.finite_array, "q", [1.0, NAN, 3.0]) == "INVALID_PARAMETER"
    assert _reason(V.finite_array, "q", [1.0] * 4, length=3) == "INVALID_PARAMETER"
    assert _reason(V.finite_array, "q", [0.0] * 11, max_len=10) == "INVALID_PARAMETER"
    assert V.name("task", "Square", known=["Square"]) == "Square"
    assert V.name("task", "", allow_empty=True) == ""
    for bad in ("", "x" * (V.MAX_NAME + 1), "a\nb", "Nope"):
        assert _reason(V.name, "task", bad, known=["Square"]) == "INVALID_NAME", bad
    assert _reason(V.names, "ids", ["a"] * 11, max_items=10) == "INVALID_NAME"


def test_writable_path_stays_under_its_roots(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert V.writable_path("out", "run1") == tmp_path.resolve() / "run1"
    assert V.writable_path("out", str(Path(tempfile.gettempdir()) / "x")).name == "x"
    assert V.writable_path("out", "/srv/data/run", roots=["/srv/data"]) == Path("/srv/data/run")
    for bad in ("/etc/passwd_dir", "../" * 40 + "etc/x", "/srv/data2/run"):
        assert _reason(V.writable_path, "out", bad, roots=["/srv/data"]) == "OUTPUT_OUTSIDE_ROOTS", bad
    (tmp_path / "link").symlink_to("/etc")  # a symlink does not smuggle a path out
    assert _reason(V.writable_path, "out", "link/x") == "OUTPUT_OUTSIDE_ROOTS"
    for bad in ("", "a\x00b", "p" * (V.MAX_PATH + 1)):
        assert _reason(V.writable_path, "out", bad) == "INVALID_PATH"


def test_augmentation_config_refuses_nan_and_inf():
    """The crash of issue 19: NaN passed `t < 0` and reached rng.uniform."""
    for t, r in ((NAN, 80.0), (INF, 80.0), (0.08, NAN), (0.6, 80.0), (-0.01, 80.0), (0.08, 181.0)):
        with pytest.raises(InvalidInputError) as e:
            AugmentationConfig(translation=t, rotation_deg=r)
        assert e.value.reason == "INVALID_PARAMETER", (t, r)
    assert AugmentationConfig(translation=0.0, rotation_deg=0.0).translation == 0.0
    assert not math.isnan(AugmentationConfig().translation)

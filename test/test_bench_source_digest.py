"""bench/datagen/source_digest.py: a datagen cell records its source demos' digest, and a cell whose demos were
remade since is marked in the README's table and runs again (bench/datagen/run.py), while the others are skipped."""
from __future__ import annotations

import sys

from conftest import REPO

sys.path.insert(0, str(REPO))
from bench import readme_table  # noqa: E402
from bench.datagen import run, source_digest  # noqa: E402


def _demos(tmp_path):
    d = tmp_path / "bags" / "Coffee"
    (d / "demo_00").mkdir(parents=True, exist_ok=True)
    (d / "demo_00" / "demo_00_0.mcap").write_bytes(b"bag")
    (d / "subsets.yaml").write_text("task: Coffee\n")
    return d


def test_the_digest_follows_every_files_bytes_and_name(tmp_path):
    d = _demos(tmp_path)
    first = source_digest.digest(d)
    assert source_digest.digest(d) == first
    (d / "demo_00" / "demo_00_0.mcap").write_bytes(b"bah")
    assert source_digest.digest(d) != first
    (d / "demo_00" / "demo_00_0.mcap").write_bytes(b"bag")
    assert source_digest.digest(d) == first
    (d / "demo_00" / "demo_00_0.mcap").rename(d / "demo_00" / "demo_01_0.mcap")
    assert source_digest.digest(d) != first


def _cell(rec, **kw):
    return {"task": "Coffee", "variant": "D2", "method": "skillgen", "augment": False, "profile": "paper",
            "attempts": 200, "seed": 1000, "rate": 0.37, "wilson95": [0.31, 0.44], "paper_rate": 70.0,
            "source_demos": rec, **kw}


def test_a_cell_is_stale_once_its_demos_are_remade_and_unknown_without_a_record(tmp_path):
    d = _demos(tmp_path)
    cell = _cell(source_digest.record(d))
    assert source_digest.is_stale(cell) is False
    (d / "demo_00" / "demo_00_0.mcap").write_bytes(b"remade")
    source_digest._current.cache_clear()
    assert source_digest.is_stale(cell) is True
    assert source_digest.is_stale(_cell(None)) is None   # measured before digests were recorded
    assert source_digest.is_stale(_cell({"dir": str(tmp_path / "gone"), "sha256": "0"})) is None


def test_a_rerun_skips_current_cells_and_runs_stale_ones_and_the_table_marks_them(tmp_path):
    d = _demos(tmp_path)
    source_digest._current.cache_clear()
    current = _cell(source_digest.record(d))
    stale = _cell({"dir": str(d), "sha256": "0" * 64}, variant="D1")
    old = _cell(None, variant="D0")
    done = run._done({"cells": [current, stale, old]}, 200, 1000)
    assert done == {("Coffee", "D2", "skillgen", "paper"), ("Coffee", "D0", "skillgen", "paper")}
    assert run._done({"cells": [current]}, 100, 1000) == set()   # other attempts: not the same cell
    assert readme_table._fmt(stale)[0].endswith(readme_table.STALE_MARK)
    assert readme_table.STALE_MARK not in readme_table._fmt(current)[0]

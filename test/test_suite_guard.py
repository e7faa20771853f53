"""The suite's own guard (test/conftest.py, issue 19): a test module that collects no tests fails the
run, also when scripts/test.sh spreads the files over pytest-xdist workers (each worker collects;
the controller, which decides the exit status, does not)."""
from __future__ import annotations

import pytest

from conftest import REPO


@pytest.mark.parametrize("workers", [[], ["-n", "2", "--dist", "loadfile"]], ids=["serial", "xdist"])
def test_a_module_without_tests_fails_the_run(pytester, workers):
    pytester.makeconftest((REPO / "test" / "conftest.py").read_text())
    pytester.makepyfile(test_full="def test_one():\n    assert True\n", test_empty='"""no tests here"""\n')
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-q", *workers, timeout=180)
    result.assert_outcomes(passed=1)
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    assert "test modules that collected no tests: test_empty.py" in result.stderr.str()

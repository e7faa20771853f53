"""bench/reliability/suite_runs.py: the summary parser and the streak rule (the records it appends are what
issue 19's "10 runs in a row" is counted from)."""
from bench.reliability.suite_runs import loaded, streak, summary


def test_summary_reads_pytest_last_line_counts():
    log = "....\n0.51s call test/x.py::t\n=== 758 passed, 2 skipped in 1075.32s (0:17:55) ===\n"
    line, counts = summary(log)
    assert line.startswith("758 passed, 2 skipped")
    assert counts == {"passed": 758, "skipped": 2}
    assert summary("FAILED test/a.py::b - x\n1 failed, 3 passed, 1 error in 2.0s\n")[1] == \
        {"failed": 1, "passed": 3, "errors": 1}
    assert summary("collected nothing\n") == ("", {})


def test_streak_counts_back_over_passing_clean_runs_of_the_same_code():
    def run(tree, rc=0, dirty=False, loaded=True):
        return {"code_tree": tree, "rc": rc, "dirty": dirty, "loaded": loaded}
    assert streak([run("a"), run("a"), run("a")]) == 3
    assert streak([run("a"), run("a", rc=1), run("a"), run("a")]) == 2
    assert streak([run("a"), run("a"), run("b")]) == 1          # new code starts a new streak
    assert streak([run("a"), run("a", dirty=True)]) == 0
    # the goal is runs under load: a quiet pass is skipped, a quiet failure still breaks the streak
    assert streak([run("a"), run("a", loaded=False), run("a")]) == 2
    assert streak([run("a"), run("a", rc=1, loaded=False), run("a")]) == 1


def test_records_before_the_loaded_field_read_their_load_from_busy_processes_and_beside():
    assert loaded({"busy_processes": 2, "beside": ""})
    assert loaded({"busy_processes": 0, "beside": "bench/hsp/run.py, 2 processes"})
    assert not loaded({"busy_processes": 0, "beside": "nothing (quiet machine)"})
    assert not loaded({"busy_processes": 0, "beside": ""})
    assert not loaded({"busy_processes": 2, "beside": "", "loaded": False})   # the field decides when present

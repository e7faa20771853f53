"""Fuzzing every node's services and actions with hypothesis (issue 19): generated requests
(helpers/fuzz_cases.py) are each answered with a result or a reason code, within the timeout, with
no exception in any node's log, and the node still serves a valid request afterwards.

Few examples per interface here (derandomized: the same cases every run, so the suite cannot
flake); bench/reliability/run.py runs many more and writes bench/results/reliability.json.
"""
from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings

from conftest import next_domain_id
from helpers.fuzz_cases import INTERFACES, call, still_serves
from helpers.ros_calls import boundary_graphs

EXAMPLES = 6


@pytest.fixture(scope="module")
def fuzz_graph(tmp_path_factory):
    with boundary_graphs(next_domain_id(), tmp_path_factory.mktemp("fuzz"), "fuzz_client") as got:
        yield got


@pytest.mark.parametrize("name", list(INTERFACES))
def test_every_generated_request_is_answered_and_the_node_keeps_serving(fuzz_graph, name):
    calls, graphs = fuzz_graph
    iface = INTERFACES[name]
    problems: list[str] = []

    @settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    @given(iface.strategy)
    def one(request):
        problem = iface.problem(call(calls, iface, request))
        if problem:
            problems.append(f"{problem}: {request}")

    one()
    assert not problems, "\n".join(problems[:5])
    assert still_serves(calls, iface), f"{name}: no valid answer after the fuzzing"
    for g in graphs:
        g.check_alive()
        assert "Traceback" not in g.output(), g.output()[-3000:]

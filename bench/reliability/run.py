"""Reliability figures (issue 19): every node's services and actions fuzzed with generated requests
(test/helpers/fuzz_cases.py, the suite's cases with many more examples), and the malformed-file
cases of test/test_malformed_files.py counted. Per interface: cases tried, problems found (no
answer within 60 s, no reason code, INTERNAL_ERROR), whether the node still served a valid
request afterwards, and whether any node logged a traceback.

    PYTHONPATH=$PWD python bench/reliability/run.py [--examples 200] [--only generate,plan_to_pose] [--fresh]

Resumable: interfaces already in bench/results/reliability.json are skipped unless --fresh (or
named in --only, which re-runs them).
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(REPO), str(REPO / "test")]
from bench.machine import machine_info  # noqa: E402
from skillgen_ros import rosenv  # noqa: E402,F401  (loopback discovery before rclpy)

OUT = REPO / "bench" / "results" / "reliability.json"


def _fuzz(calls, graphs, iface, examples: int) -> dict:
    from hypothesis import HealthCheck, given, settings

    from helpers.fuzz_cases import call, still_serves

    tried, problems = [0], []

    @settings(max_examples=examples, deadline=None, database=None, suppress_health_check=list(HealthCheck))
    @given(iface.strategy)
    def one(request):
        tried[0] += 1
        problem = iface.problem(call(calls, iface, request))
        if problem:
            problems.append(f"{problem}: {str(request)[:300]}")

    t0 = time.monotonic()
    one()
    serves = bool(still_serves(calls, iface))
    tracebacks = sum(g.output().count("Traceback") for g in graphs)
    return {"cases": tried[0], "failures": len(problems), "examples": problems[:5], "still_serves": serves,
            "tracebacks_in_logs": tracebacks, "seconds": round(time.monotonic() - t0, 1)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--examples", type=int, default=200)
    ap.add_argument("--only", default="", help="comma-separated interface names")
    ap.add_argument("--fresh", action="store_true")
    ap.add_argument("--domain", type=int, default=96)
    a = ap.parse_args()
    from helpers.fuzz_cases import INTERFACES
    from helpers.ros_calls import boundary_graphs

    doc = json.loads(OUT.read_text()) if OUT.is_file() and not a.fresh else {}
    doc.setdefault("interfaces", {})
    wanted = [n for n in (a.only.split(",") if a.only else INTERFACES) if n]
    todo = wanted if a.only else [n for n in wanted if n not in doc["interfaces"]]  # --only re-runs those
    with tempfile.TemporaryDirectory() as art, boundary_graphs(a.domain, Path(art)) as (calls, graphs):
        for name in todo:
            doc["interfaces"][name] = {**_fuzz(calls, graphs, INTERFACES[name], a.examples), "examples_asked": a.examples}
            doc.update(command="PYTHONPATH=$PWD python bench/reliability/run.py " + " ".join(sys.argv[1:]),
                       machine=machine_info(),
                       total_cases=sum(v["cases"] for v in doc["interfaces"].values()),
                       total_failures=sum(v["failures"] for v in doc["interfaces"].values()))
            OUT.write_text(json.dumps(doc, indent=2) + "\n")  # after each interface: resumable
            print(f"{name}: {doc['interfaces'][name]['cases']} cases, {doc['interfaces'][name]['failures']} failures",
                  flush=True)
    try:
        from test_malformed_files import CASES as MALFORMED
        doc["malformed_files"] = {"cases": len(MALFORMED), "kinds": sorted({k.split(":")[0] for k in MALFORMED})}
        OUT.write_text(json.dumps(doc, indent=2) + "\n")
    except ImportError:
        pass
    return 0 if all(v["failures"] == 0 and v["still_serves"] for v in doc["interfaces"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())

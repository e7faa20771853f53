"""Chaos (issue 19; a benchmark): kill -9 each process of the datagen graph in turn during `generate`
runs through `skillgen launch datagen --respawn` (simulated Panda, recorder on), `--rounds` times
each, and count the kills survived with nothing lost (skillgen_ros/testing/chaos.py judges each:
every finished attempt in demo.hdf5 or failed.hdf5 with its reason, demo.hdf5 valid, the bag
readable (recovered if the recorder died), the node respawned and later attempts succeeding).

    PYTHONPATH=$PWD python bench/chaos/run.py --rounds 3            # 15 kills
    PYTHONPATH=$PWD python bench/chaos/run.py --rounds 1 --victims perception   # one kill

Writes the "chaos" section of bench/results/reliability.json (or --out); resumable: kills already
recorded for (victim, round) are kept unless --fresh. Round r runs seed r.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
from bench.machine import machine_info  # noqa: E402
from skillgen_ros import rosenv  # noqa: E402,F401  (loopback discovery before rclpy)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--victims", nargs="+", default=None)
    ap.add_argument("--output", default="", help="run directory (default: a fresh temp dir)")
    ap.add_argument("--out", default=str(REPO / "bench" / "results" / "reliability.json"))
    ap.add_argument("--fresh", action="store_true", help="forget kills recorded before")
    a = ap.parse_args()
    from skillgen_ros.cli.launcher import graph_client
    from skillgen_ros.client import SkillGenClient
    from skillgen_ros.testing import chaos
    from skillgen_ros.testing.domains import acquire_domain

    victims = a.victims or list(chaos.VICTIMS)
    path = Path(a.out)
    doc = json.loads(path.read_text()) if path.exists() else {}
    kills = [] if a.fresh else list(doc.get("chaos", {}).get("kills", []))
    done = {(k["victim"], k["round"]) for k in kills}
    todo = [(r, v) for r in range(a.rounds) for v in victims if (v, r) not in done]
    run_dir = Path(a.output or tempfile.mkdtemp(prefix="skillgen_chaos_"))
    lease = acquire_domain()
    os.environ["ROS_DOMAIN_ID"] = str(lease.id)
    roots = ["--ros-args", "-p", f"datagen:writable_roots:=['{run_dir}']", *chaos.FAST_TIMEOUTS]
    t0 = time.monotonic()

    def client():
        c = SkillGenClient(domain_id=lease.id)
        if not c.wait_for_server(600):
            raise SystemExit("datagen did not come up")
        return c

    with graph_client("datagen", lambda: SkillGenClient(domain_id=lease.id), "datagen 'generate'", 600,
                      ros_args=roots, respawn=True) as (g, _probe):
        for r, v in todo:
            out = run_dir / f"{v}_{r}"
            rec = chaos.kill_mid_run(g.pid, client, v, out, seed=r,
                                     stop_recording=lambda: chaos.stop_recording(lease.id))
            kills.append({"victim": v, "round": r, "survived": rec.survived,
                          **{k: val for k, val in dataclasses.asdict(rec).items() if k != "reasons"},
                          "attempt_reasons": {str(i): why for i, why in rec.reasons.items()}})
            print(json.dumps(kills[-1]), flush=True)
            _save(path, doc, kills, a, victims)  # resumable after each kill
    lease.release()
    print(json.dumps(doc["chaos"]["summary"], indent=2))
    print(f"{len(todo)} kills in {time.monotonic() - t0:.0f} s")
    return 0


def _save(path: Path, doc: dict, kills: list, a, victims) -> None:
    per = {}
    for k in kills:
        s = per.setdefault(k["victim"], {"kills": 0, "survived": 0, "in_flight_reasons": {}})
        s["kills"] += 1
        s["survived"] += bool(k["survived"])
        why = k["attempt_reasons"].get(str(k["in_flight"]), "not finished")
        s["in_flight_reasons"][why] = s["in_flight_reasons"].get(why, 0) + 1
    doc["chaos"] = {
        "command": "PYTHONPATH=$PWD python bench/chaos/run.py " + " ".join(sys.argv[1:]),
        "machine": machine_info(),
        "goal": "Square D0 skillgen, 3 successes (at most 20 attempts), record_bag; the kill lands once attempt 0 is done",
        "summary": {"kills": len(kills), "survived_nothing_lost": sum(bool(k["survived"]) for k in kills),
                    "per_victim": per},
        "kills": kills,
    }
    path.write_text(json.dumps(doc, indent=2) + "\n")


if __name__ == "__main__":
    sys.exit(main())

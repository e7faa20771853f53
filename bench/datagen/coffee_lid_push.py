"""bench/datagen/coffee_lid_push.py: is Coffee D2's gap our demonstrator's wrist turn?

Our human-like demonstrator used to turn the hand 90 deg between letting the pod go and pushing the lid shut
(core/demonstrator/human_like.py `LID_PUSH_TURNS = True`, the demos shipped until 2026-12-06); SkillGen replays
that turn rigidly, and in Coffee D2's machine turned 150-240 deg it runs panda_joint7 onto its limit
(docs/tasks.md). The shipped bags/Coffee now push the lid at the pod grasp's yaw (4 cm lower, where the finger
base meets the lid). This makes ten demos with the turn in out/demos/coffee_lid_turn/ and runs the same attempts
(seed, profile, noise) from them and from the shipped bags/Coffee, counting successes and the attempts with a
joint on its limit in a skill. An experiment on our source demos, not a baseline.

    .venv/bin/python bench/datagen/coffee_lid_push.py [--variants D2] [--attempts 40] [--seed 1000]

Writes bench/results/coffee_lid_push.json (its first run, 2026-12-06, compared the then-shipped turning demos with
no-turn demos made by this script in out/demos/coffee_lid_no_turn/, the demonstrator and seeds bags/Coffee now
ships).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.datagen.diagnose import diagnose  # noqa: E402
from bench.datagen.demo_style import add_settings, make_demos, same_settings, settings  # noqa: E402
from bench.machine import machine_info  # noqa: E402

OUT = ROOT / "bench" / "results" / "coffee_lid_push.json"
TURN = ROOT / "out" / "demos" / "coffee_lid_turn"
ARMS = ("turn (the demos shipped until 2026-12-06)", "no turn (shipped since 2026-12-06)")
KEEP = ("successes", "rate", "failures", "by_source_demo", "joint_at_limit_in_a_skill", "wall_seconds")


def make_turn_demos(force: bool) -> Path:
    """Ten Coffee demos from the demonstrator with LID_PUSH_TURNS on (made once, or again with --force)."""
    return make_demos("Coffee", TURN, force, LID_PUSH_TURNS=True)


def _kept(a) -> dict:
    """What OUT holds from the same settings that this run keeps: the other variants' results (a run of D2
    keeps D0's) and, with them, their arms' provenance note."""
    old = json.loads(OUT.read_text()) if OUT.exists() else {}
    if not same_settings(old, a):
        return {"variants": {}}
    variants = {v: r for v, r in old.get("variants", {}).items() if v not in a.variants}
    note = {"arms_relabelled": old["arms_relabelled"]} if variants and "arms_relabelled" in old else {}
    return {"variants": variants, **note}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", nargs="+", default=["D2"])
    add_settings(ap)
    a = ap.parse_args(argv)
    t0 = time.time()
    arms = {ARMS[0]: make_turn_demos(a.force_demos), ARMS[1]: ROOT / "bags" / "Coffee"}
    out = {"experiment": __doc__.splitlines()[2].strip(), "machine": machine_info(), **settings(a), **_kept(a)}
    for v in a.variants:
        out["variants"][v] = {}
        for arm, bags in arms.items():
            e = diagnose("Coffee", v, a.attempts, a.noise, a.seed, a.profile, bags=bags)
            out["variants"][v][arm] = {k: e[k] for k in KEEP}
            j7 = e["joint_at_limit_in_a_skill"].get("panda_joint7", {"attempts": 0, "successes": 0})
            print(f"Coffee {v} {arm}: {e['successes']}/{a.attempts}; panda_joint7 on its limit in "
                  f"{j7['attempts']} attempts ({j7['successes']} succeeded)", flush=True)
    out["command"] = (f".venv/bin/python bench/datagen/coffee_lid_push.py --variants {' '.join(out['variants'])} "
                      f"--attempts {a.attempts} --seed {a.seed}")
    out["wall_seconds"] = time.time() - t0
    OUT.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

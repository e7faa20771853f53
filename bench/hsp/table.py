"""The README's HSP table, from bench/results/hsp.json (bench/hsp/run.py); used by bench/readme_table.py.

One row per cell with each method's best checkpoint (success rate and 95% Wilson interval) beside
the paper's Fig. 5 number, then the protocol the numbers came from (demos, rollouts, per-network
budget and sizes, training time), since a CPU budget is not robomimic's 200k steps.
"""
from __future__ import annotations

from bench.hsp.results import METHODS as _RUN_METHODS
from bench.hsp.results import GOAL_PAIR, NETWORK, class_minus_bc, goal_cell, paper_class_minus_bc

# the paper's Fig. 5 column order: the baseline first; the names are run.py's
METHODS = ("MimicGen-BC",) + tuple(m for m in _RUN_METHODS if m != "MimicGen-BC")


def _best(cell: dict, method: str) -> str:
    b = cell.get("methods", {}).get(method, {}).get("best")
    if not b:
        return "not run"
    lo, hi = b["wilson_95"]
    return f"{100 * b['success_rate']:.0f}% ({100 * lo:.0f}-{100 * hi:.0f}; {b['successes']}/{b['rollouts']})"


def _budget(rec: dict) -> str:
    """A network's (or a run's) training budget: wall minutes (checked at chunk ends) and/or steps."""
    parts = []
    if rec.get("budget_minutes"):
        parts.append(f"{rec['budget_minutes']:g} training minutes")
    if rec.get("budget_steps") and (not parts or rec["budget_steps"] < 200_000):
        parts.append(f"{rec['budget_steps']} steps")
    return " or ".join(parts) + " budget"


def _network_line(name: str, cell: dict) -> str:
    parts = []
    for net, label in (("hsp", "HSP networks (pi shared, T, Class, Reg)"), ("bc", "MimicGen BC-RNN-GMM")):
        n = cell.get("networks", {}).get(net)
        if not n:
            continue
        ds = cell.get("datasets", {}).get(net, {})
        rate = ds.get("generation_rate")
        gen = f"{ds.get('demos', '?')} demos from {ds.get('attempts', '?')} attempts" + \
            (f" ({100 * rate:.0f}%)" if rate else "")
        parts.append(f"{label}: {n['steps']} steps ({_budget(n)}) in {n['train_seconds'] / 60:.0f} min "
                     f"({n.get('ms_per_train_step', 0):.0f} ms/step, LSTM {n['hidden']}, MLP {n['mlp_hidden']}), "
                     f"data {gen}")
    return f"- {name}: " + "; ".join(parts) if parts else ""


def hsp_rows(data: dict) -> list[str]:
    """Markdown lines (empty when the benchmark has not run)."""
    cells = data.get("cells", {})
    if not cells:
        return []
    proto = data.get("protocol", {})
    budgets = {_budget(n) for c in cells.values() for n in c.get("networks", {}).values()} or {_budget(proto)}
    budget = f"{budgets.pop()} per network" if len(budgets) == 1 else "the training budget listed per cell below"
    out = [f"HSP and the MimicGen BC baseline (bench/hsp/run.py; best checkpoint over evaluations every "
           f"{proto.get('chunk_steps')} steps, {proto.get('rollouts')} rollouts each on held-out reset seeds, "
           f"{budget}, low-dim observations, CPU; ours with 95% Wilson interval, paper's Fig. 5):", "",
           "| cell | " + " | ".join(f"{m} | paper" for m in METHODS) + " |", "|" + "---|" * (1 + 2 * len(METHODS))]
    for name, c in cells.items():
        paper = c.get("paper", {})
        row = [name]
        for m in METHODS:
            row += [_best(c, m), "" if paper.get(m) is None else f"{paper[m]:g}%"]
        out.append("| " + " | ".join(row) + " |")
    out += [""] + [line for n, c in cells.items() if (line := _network_line(n, c))]
    for n, c in cells.items():
        again = {m: r["reevaluated"] for m, r in c.get("methods", {}).items() if "reevaluated" in r}
        if again:
            steps = sorted({s for r in again.values() for s in r.get("steps", [])})
            reason = next(iter(again.values())).get("reason", "")
            out.append(f"- {n}: {', '.join(again)} evaluated again on the kept checkpoints (steps {steps}): {reason}.")
    s = data.get("summary", {})
    gap = s.get("hsp_class_minus_bc_d1_d2_points")
    if gap is not None:
        out.append(f"- HSP-Class minus MimicGen BC on the D1/D2 cells run: {gap:+.1f} points (goal >= +20).")
    out.append("- Cells not listed have not run yet; the paper's 18-variant averages (HSP-TAMP 85.7, HSP-Class 82.9, "
               "HSP-Reg 72.6, MimicGen 59.1) compare with no subset of them.")
    return out


def budget_rows(base: dict, longer: dict, path: str = "bench/results/hsp_budget3x.json") -> list[str]:
    """The budget's cost on one cell (issue 23): the same networks trained on past the budget (`path`: a copy
    of the base file trained on, or a new --out that resumed the base's last.pt), best success per method at
    the budget and the best so far (the budget's own included), then every evaluation past the budget."""
    out = []
    for name, c in longer.get("cells", {}).items():
        b = base.get("cells", {}).get(name, {})
        parts = []
        for m in METHODS:
            evals = c.get("methods", {}).get(m, {}).get("evals", [])
            at = b.get("methods", {}).get(m, {}).get("best")
            if not evals or not at:
                continue
            best = max([at] + evals, key=lambda e: e["successes"])
            budget = b.get("networks", {}).get(NETWORK[m], {}).get("steps", at["step"])
            later = ", ".join(f"{e['successes']} at {e['step'] / 1000:g}k" for e in evals if e["step"] > budget)
            parts.append(f"{m} {at['successes']}/{at['rollouts']} -> {best['successes']}/{best['rollouts']} "
                         f"(step {best['step']}" + (f"; {later}" if later else "") + ")")
        if parts:
            proto = longer.get("protocol", {})
            goal = (f"{proto['budget_minutes']} min" if proto.get("budget_minutes") else
                    f"{proto.get('budget_steps', '?')} steps")
            sofar = "; ".join(f"{k}: {_trained(v)}" for k, v in c.get("networks", {}).items())
            out.append(f"- Longer training, {name} ({path}, goal {goal} per network; so far {sofar}): "
                       "best at the budget -> best so far: " + ", ".join(parts) + ".")
    return out


def equal_budget_gap_rows(base: dict, longer: dict, path: str) -> list[str]:
    """HSP-Class minus MimicGen BC with both networks trained past the budget to the same step (issue 23's
    goal measure at a longer, equal budget): per D1/D2 cell of `longer` with both, each method's best over the
    base file's evaluations and the longer run's up to the step both reached, beside the gap at the budget."""
    out, pair = [], GOAL_PAIR
    for name, c in longer.get("cells", {}).items():
        b = base.get("cells", {}).get(name, {})
        evals = {m: c.get("methods", {}).get(m, {}).get("evals", []) for m in pair}
        at = {m: b.get("methods", {}).get(m, {}).get("best") for m in pair}
        if not goal_cell(name) or not all(evals.values()) or not all(at.values()):
            continue
        common = min(max(e["step"] for e in evals[m]) for m in pair)
        best = {m: max([at[m]] + [e for e in evals[m] if e["step"] <= common], key=lambda e: e["successes"])
                for m in pair}
        gap = {k: 100 * (v[pair[0]]["successes"] / v[pair[0]]["rollouts"]
                         - v[pair[1]]["successes"] / v[pair[1]]["rollouts"]) for k, v in (("at", at), ("best", best))}
        paper = paper_class_minus_bc([name])
        both = ", ".join(f"{m} {best[m]['successes']}/{best[m]['rollouts']} (step {best[m]['step']})" for m in pair)
        out.append(f"- HSP-Class minus MimicGen BC at an equal longer budget, {name} ({path}; both networks to "
                   f"{common} steps, best checkpoint each, the budget's evaluations included): {both}: "
                   f"{gap['best']:+.1f} points (at the budget {gap['at']:+.1f}; paper {paper:+.1f}).")
    return out


def _trained(net: dict) -> str:
    """'22500 steps in 79 min', or for a network resumed from another run's last.pt (a record that timed only
    the steps it trained) '13500 steps, the last 9300 in 22 min'."""
    timed = net.get("timed_steps", net["steps"])
    if timed == net["steps"]:
        return f"{net['steps']} steps in {net['train_seconds'] / 60:.0f} min"
    return f"{net['steps']} steps, the last {timed} in {net['train_seconds'] / 60:.0f} min"


def size_rows(base: dict, longer: dict, small: dict) -> list[str]:
    """A smaller LSTM on the same data and budget (issue 23 allows one that costs at most ~5 points):
    per method, the best at the budget for each size (`base`: robomimic's size), and both at the
    steps they share (`longer`: the same robomimic-size networks trained on, evaluated at more steps)."""
    out = []
    for name, c in small.get("cells", {}).items():
        b = base.get("cells", {}).get(name, {})
        n, nb = c.get("networks", {}).get("hsp"), b.get("networks", {}).get("hsp")
        if not n or not nb:
            continue
        parts = []
        for m in METHODS:
            mine = c.get("methods", {}).get(m, {})
            theirs = b.get("methods", {}).get(m, {})
            if "best" not in mine or "best" not in theirs:
                continue
            evals = longer.get("cells", {}).get(name, {}).get("methods", {}).get(m, {}).get("evals", [])
            shared = {e["step"]: e for e in evals or theirs.get("evals", [])}
            same = [f"{e['successes']} vs {shared[e['step']]['successes']} at {e['step']}"
                    for e in mine["evals"] if e["step"] in shared]
            parts.append(f"{m} {mine['best']['successes']}/{mine['best']['rollouts']} (step {mine['best']['step']}) vs "
                         f"{theirs['best']['successes']}/{theirs['best']['rollouts']} (step {theirs['best']['step']})"
                         + (f" [same steps: {', '.join(same)}]" if same else ""))
        if parts:
            out.append(f"- LSTM {n['hidden']} vs {nb['hidden']}, {name}, same data "
                       f"(bench/results/hsp_h{n['hidden']}.json; {n['steps']} steps in {n['train_seconds'] / 60:.0f} min, "
                       f"{n.get('ms_per_train_step', 0):.0f} ms/step, vs {nb['steps']} in "
                       f"{nb['train_seconds'] / 60:.0f} min; best so far vs best within the budget, then "
                       f"successes at the same steps): " + "; ".join(parts) + ".")
    return out


def reg_target_rows(data: dict) -> list[str]:
    """HSP-Reg with I retrained on each target (bench/hsp/retrain_reg.py), pi and T unchanged."""
    runs = data.get("runs", {})
    if not runs:
        return []
    parts = []
    for key, r in sorted(runs.items()):
        e = r["evaluation"]
        lo, hi = e["wilson_95"]
        parts.append(f"{key.rsplit('/', 2)[0]} I on {r['target']}, seed {r['seed']}: {e['successes']}/{e['rollouts']} "
                     f"({100 * lo:.0f}-{100 * hi:.0f}%; failures {e['failures']})")
    return ["- HSP-Reg's target (bench/results/hsp_reg_target.json; I retrained alone for the checkpoint's own "
            "steps, pi and T unchanged): " + "; ".join(parts) + "."]


def termination_rows(data: dict, base: dict) -> list[str]:
    """HSP-Class / HSP-Reg with T retrained on another label rule (bench/hsp/retrain_termination.py), pi and I
    unchanged, beside the same checkpoint's own T (the paper's rule) from the benchmark (`base`: hsp.json)."""
    parts = []
    for key, r in sorted(data.get("runs", {}).items()):
        cell, step = "/".join(key.split("/")[:2]), r["checkpoint_step"]
        own = base.get("cells", {}).get(cell, {}).get("methods", {})
        for m, e in sorted(r["evaluations"].items()):
            mine = next((x for x in own.get(m, {}).get("evals", []) if x["step"] == step), None)
            lo, hi = e["wilson_95"]
            parts.append(f"{cell} step {step} {m}, T on {r['labels']} labels, seed {r['seed']}: {e['successes']}/"
                         f"{e['rollouts']} ({100 * lo:.0f}-{100 * hi:.0f}%; skill endings {e['skill_endings']}; "
                         f"{e['mean_steps']:.0f} steps a rollout)"
                         + (f" vs its own T {mine['successes']}/{mine['rollouts']} (skill endings "
                            f"{mine['skill_endings']}; {mine['mean_steps']:.0f} steps)" if mine else ""))
    if not parts:
        return []
    return ["- T's labels, ours (bench/results/hsp_termination_labels.json; T retrained alone for the checkpoint's "
            "own steps, pi and I unchanged, the benchmark's reset seeds): " + "; ".join(parts) + "."]


def observation_rows(old: dict, new: dict) -> list[str]:
    """The same protocol before and after the networks read each object's pose in the hand frame
    (`object_to_eef`; docs/hsp.md "Observations"): best per method, world poses only -> both."""
    out = []
    for name, c in new.get("cells", {}).items():
        o = old.get("cells", {}).get(name, {})
        parts = [f"{m} {o['methods'][m]['best']['successes']}/{o['methods'][m]['best']['rollouts']} -> "
                 f"{c['methods'][m]['best']['successes']}/{c['methods'][m]['best']['rollouts']}"
                 for m in METHODS if "best" in o.get("methods", {}).get(m, {}) and "best" in c["methods"].get(m, {})]
        if parts:
            out.append(f"- {name}, world object poses only (bench/results/hsp_absolute_obs.json, before 2026-12-03) -> "
                       f"with each object's pose in the hand frame (robomimic's object state), same protocol: "
                       + ", ".join(parts) + ". The rows below were measured with world poses only.")
    return out


def _paired_bests(base: dict, run: dict) -> list[tuple[str, dict, dict]]:
    """(method, base cell's best, run cell's best) for each method both cells have a best checkpoint for."""
    out = []
    for m in METHODS:
        theirs = base.get("methods", {}).get(m, {}).get("best")
        mine = run.get("methods", {}).get(m, {}).get("best")
        if theirs and mine:
            out.append((m, theirs, mine))
    return out


# the paper's HSP-Class on 200 SkillGen demos (Appendix "Data scaling", Table table:scaling_mp_class)
PAPER_CLASS_200 = {"Square/D2": 74.0}


def demos_rows(base: dict, few: dict) -> list[str]:
    """The same protocol on 200 demos instead of 1000 (`few`: bench/results/hsp_200demos.json) beside
    the paper's data-scaling table, per method run on both."""
    out = []
    for name, c in few.get("cells", {}).items():
        b = base.get("cells", {}).get(name, {})
        n = c.get("datasets", {}).get("hsp", {})
        parts = []
        for m, theirs, mine in _paired_bests(b, c):
            paper = f", paper {PAPER_CLASS_200[name]:g}% on 200" if m == "HSP-Class" and name in PAPER_CLASS_200 else ""
            parts.append(f"{m} {mine['successes']}/{mine['rollouts']} vs {theirs['successes']}/{theirs['rollouts']}{paper}")
        if parts:
            out.append(f"- {n.get('demos', '?')} demos vs 1000, {name}, same network sizes, steps and rollouts "
                       f"(bench/results/hsp_200demos.json; data from {n.get('attempts', '?')} attempts): "
                       + "; ".join(parts) + ".")
    return out


def device_rows(base: dict, *runs: dict) -> list[str]:
    """Networks trained on a lent GPU (bench/hsp/device.py, bench/results/hsp_cuda_*.json), evaluated
    here on the same held-out seeds: per method the successes at each returned step, beside the CPU
    run's best (`base`)."""
    out = []
    for run in runs:
        for name, c in run.get("cells", {}).items():
            b = base.get("cells", {}).get(name, {})
            for net, n in c.get("networks", {}).items():
                parts = []
                for m in METHODS:
                    evals = sorted(c.get("methods", {}).get(m, {}).get("evals", []), key=lambda e: e["step"])
                    if not evals:
                        continue
                    cpu = sorted(b.get("methods", {}).get(m, {}).get("evals", []), key=lambda e: e["step"])
                    at = ", ".join(f"{e['successes']}/{e['rollouts']} at {e['step'] / 1000:g}k" for e in evals)
                    if cpu:
                        wins = "/".join(str(e["successes"]) for e in cpu)
                        steps = "/".join(f"{e['step'] / 1000:g}" for e in cpu)
                        at += f" (the CPU run: {wins} at {steps}k)"
                    parts.append(f"{m} {at}")
                if parts:
                    out.append(f"- {name}, {net} networks trained on a lent GPU ({n['device']}, torch {n['torch']}; "
                               f"bench/hsp/device.py, same data, sizes and seed, evaluated here): {n['steps']} steps "
                               f"in {n['train_seconds'] / 60:.1f} min ({n['ms_per_train_step']:.1f} ms/step): "
                               + "; ".join(parts) + ".")
    return out


def _skill0_endings(cell: dict, method: str) -> str:
    """How skill 0 ended in the best evaluation: T's (or TAMP's) goal vs the 400-step budget."""
    b = cell.get("methods", {}).get(method, {}).get("best") or {}
    e = next((x for x in cell["methods"][method].get("evals", []) if x["step"] == b.get("step")), {})
    ends = e.get("skill_endings", {}).get("0", {})
    done = ends.get("termination", 0) + ends.get("goal", 0)  # T (HSP-Class/Reg) or the privileged goal (HSP-TAMP)
    return f"skill 0 ended by T/goal {done}, budget {ends.get('budget', 0)}" if ends else ""


def _v2_network(c: dict, network: str) -> str:
    """A v2 network's data and training: '; v2 data [for MimicGen-BC] N demos from M attempts, S steps in T min'."""
    ds, net = c.get("datasets", {}).get(network, {}), c.get("networks", {}).get(network)
    if not net:
        return ""
    return (f"; v2 data{' for MimicGen-BC' if network == 'bc' else ''} {ds.get('demos', '?')} demos from "
            f"{ds.get('attempts', '?')} attempts, {_trained(net)}")


def source_demo_rows(old: dict, new: dict) -> list[str]:
    """A cell re-run on data generated from the v2 source demos (`new`: bench/results/hsp_v2.json, same protocol)
    beside the benchmark's cell from the earlier demos (`old`: hsp.json): best per method and how skill 0 ended
    (the v2 demos lift as soon as the fingers stop, which may let T see the grasp end; docs/hsp.md)."""
    out = []
    for name, c in new.get("cells", {}).items():
        o = old.get("cells", {}).get(name, {})
        parts = []
        for m, theirs, mine in _paired_bests(o, c):
            ends = [x for x in (_skill0_endings(o, m), _skill0_endings(c, m)) if x]
            parts.append(f"{m} {theirs['successes']}/{theirs['rollouts']} -> {mine['successes']}/{mine['rollouts']}"
                         + (f" ({' -> '.join(ends)})" if len(ends) == 2 else ""))
        run = "".join(_v2_network(c, k) for k in ("hsp", "bc"))
        # a cell still training (a session ended mid-run) says so: its best is not the full budget's
        busy = [(k, n) for k, n in c.get("networks", {}).items() if not n.get("finished", True)]
        how = ("same protocol, steps and reset seeds; best checkpoint each" if not busy else
               "UNFINISHED: " + ", ".join(f"{k} {n['steps']} of {n.get('budget_steps', '?')} steps" for k, n in busy)
               + " so far, same protocol and reset seeds; best checkpoint so far each")
        if parts:
            out.append(f"- {name}, data from the earlier demos -> from the v2 demos (bench/results/hsp_v2.json; "
                       f"{how}{run}): " + "; ".join(parts) + ".")
    return out + _v2_class_minus_bc(new)


def _v2_class_minus_bc(new: dict) -> list[str]:
    """The issue's goal (HSP-Class - MimicGen BC >= 20 points on D1/D2) on the v2 data's cells that have both,
    beside the paper's on the same cells."""
    both, ours = class_minus_bc(new)
    if not both:
        return []
    paper = paper_class_minus_bc(both)
    return [f"- HSP-Class minus MimicGen BC on the v2 data, D1/D2 cells with both ({', '.join(both)}): {ours:+.1f} "
            f"points (goal >= +20; the paper on the same cells {paper:+.1f})."]

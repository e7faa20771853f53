"""Rebuild the README's results section from bench/results/*.json (between the results markers).

    .venv/bin/python bench/readme_table.py

Each row: our current number, the paper's or the anchor's, and the benchmark JSON it came from.
Missing results show as "not run". Generation averages are taken only over cells both sides have
(bench/datagen/summary.py), per algorithm profile; the paper's 18-variant averages are quoted as
such, below the cell tables, never beside a different cell set.
"""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
RES = ROOT / "bench" / "results"
START, END = "<!-- results:start -->", "<!-- results:end -->"


DATAGEN = "datagen"  # which bench/results JSON the generation rows read (--datagen)


def load(name: str) -> dict:
    p = RES / f"{DATAGEN if name == 'datagen' else name}.json"
    return json.loads(p.read_text()) if p.exists() else {}


def get(d: dict, path: str, default=None):
    for k in path.split("."):
        if not isinstance(d, dict) or k not in d:
            return default
        d = d[k]
    return d


def pct(x) -> str:
    if x is None:
        return "not run"
    return f"{100 * x:.2f}%" if 0.995 <= x < 1.0 else f"{100 * x:.1f}%"


def ms(x) -> str:
    return "not run" if x is None else f"{1000 * x:.1f} ms"


def num(x, fmt="{:.2f}") -> str:
    return "not run" if x is None else fmt.format(x)


def _datagen_and_hsp_rows(dg: dict) -> list[tuple[str, str, str, str]]:
    """Generation throughput, the graph path, estimated poses and HSP timing."""
    out = []
    out.append(("successful demos / hour / core, Square D0 low-dim (our profile)",
                num(get(dg, "throughput_lowdim.successes_per_hour_per_core"), "{:.0f}"),
                "goal 1500; MimicGen ~100 (CPU); Isaac Lab SkillGen 500-670 (GPU)", "datagen"))
    out.append(("successful demos / hour / core, with 84x84 images (our profile)",
                num(get(dg, "throughput_images.successes_per_hour_per_core"), "{:.0f}"), "", "datagen"))
    out.append(("graph / in-process time per attempt (median of back-to-back pairs)",
                num(get(dg, "graph_overhead.ratio_graph_to_in_process")),
                "goal <= 1.5", "datagen"))
    rates = get(dg, "graph_rates.tasks") or {}
    if rates:
        n = get(dg, "graph_rates.attempts")
        same = sum(bool(v["same_outcomes"]) for v in rates.values())
        out.append((f"successes through the ROS graph / in-process, D0, estimated poses (our profile, {n} attempts a task)",
                    ", ".join(f"{t} {v['graph']['successes']} / {v['in_process']['successes']}" for t, v in rates.items()),
                    f"the same attempts succeed on both paths in {same} of {len(rates)} tasks", "datagen"))
    out.append(("success with estimated vs ground-truth poses, Square D1 (our profile)",
                f"{pct(get(dg, 'perception_estimate.rate'))} vs {pct(get(dg, 'perception_ground_truth.rate'))}", "",
                "datagen"))
    ht = load("hsp_timing")
    out.append(("HSP inference, pi + T per 20 Hz control step (1 core, LSTM 400, median / p95)",
                f"{num(get(ht, 'inference.pi_plus_T_ms_median'))} / {num(get(ht, 'inference.pi_plus_T_ms_p95'))} ms",
                "goal <= 5 ms", "hsp_timing"))
    out.append(("HSP training step, pi (BC-RNN-GMM, batch 100, seq 10; 2 threads)",
                f"{num(get(ht, 'train_step.2.policy_ms_median'), '{:.0f}')} ms",
                "robomimic 200k steps = ~6 h per network here", "hsp_timing"))
    return out


def _planning_rows(ik: dict, pl: dict) -> list[tuple[str, str, str, str]]:
    """IK and motion planning (bench/ik, bench/planning)."""
    out = []
    out.append(("IK solve rate (TRAC-IK protocol, 10k)", pct(get(ik, "ours.solve_rate")),
                "TRAC-IK 99.70%, KDL 61.77%", "ik"))
    out.append(("IK mean / median time", f"{num(get(ik, 'ours.mean_ms'))} / {num(get(ik, 'ours.median_ms'))} ms",
                "TRAC-IK 0.38 ms mean (C++)", "ik"))
    out.append(("planning success, point cloud (scene boxes, same problems)",
                f"{pct(get(pl, 'results.point_cloud.success_rate'))} ({pct(get(pl, 'results.scene.success_rate'))})",
                "goal >= 98% with 0 colliding plans (issue 19)", "planning"))
    out.append(("planning median / p95, point cloud",
                f"{ms(get(pl, 'results.point_cloud.time_median_s'))} / {ms(get(pl, 'results.point_cloud.time_p95_s'))}",
                "cuRobo 31 ms (GPU), VAMP 35 us, MoveIt RRT-Connect 100-200 ms", "planning"))
    out.append(("planned paths truly collision-free", pct(get(pl, "results.point_cloud.collision_free_fraction")),
                "must be 100%", "planning"))
    pen = get(pl, "results.point_cloud.worst_penetration_m")
    out.append(("point-cloud plans through a true box / deepest (seeds x problems)",
                "not run" if pen is None else
                f"{get(pl, 'results.point_cloud.colliding_plans')} / {1000 * pen:.1f} mm "
                f"({len(get(pl, 'seeds', []))} x {get(pl, 'problems_per_seed')})", "must be 0", "planning"))
    return out


def _perception_rows(pe: dict) -> list[tuple[str, str, str, str]]:
    """Pose estimation at 640x480 (bench/perception)."""
    out = []
    hi = "overall.hi"
    out.append(("perception ADD-S < 1 cm (640x480, depth noise)", pct(get(pe, f"{hi}.adds_lt_1cm_rate")), "goal >= 95%",
                "perception"))
    out.append(("perception median / p95 translation error",
                f"{num(get(pe, f'{hi}.trans_median_mm'))} / {num(get(pe, f'{hi}.trans_p95_mm'))} mm", "goal median <= 5 mm",
                "perception"))
    out.append(("perception median / p95 rotation error (symmetry-aware)",
                f"{num(get(pe, f'{hi}.rot_median_deg'))} / {num(get(pe, f'{hi}.rot_p95_deg'))} deg",
                "goal median <= 3 deg", "perception"))
    out.append(("perception wrong identity", pct(get(pe, f"{hi}.wrong_identity_rate")), "", "perception"))
    out.append(("perception per 640x480 frame: CPU / wall (median)",
                f"{num(get(pe, f'{hi}.cpu_median_ms'), '{:.0f}')} / {num(get(pe, f'{hi}.latency_median_ms'), '{:.0f}')} ms",
                "goal <= 100 ms on one core; FoundationPose ~110 ms (RTX 4090, 720p)", "perception"))
    out.append(("perception vs open3d FPFH+RANSAC+ICP baseline (ADD-S<1cm ratio)",
                num(get(pe, "ratios_ours_over_baseline.adds_lt_1cm_rate")), "", "perception"))
    return out


def _sim_and_recorder_rows(sd: dict, rt: dict) -> list[tuple[str, str, str, str]]:
    """The sim driver, the OSC and the recorder (bench/sim_driver, bench/recorder_throughput)."""
    out = []
    out.append(("sim RTF lockstep, no cameras / two 84x84 cameras",
                f"{num(get(sd, 'in_process_no_cameras.rtf'), '{:.1f}')} / {num(get(sd, 'in_process_cameras.rtf'), '{:.1f}')}",
                "", "sim_driver"))
    out.append(("OSC tracking error, figure-eight (mean mm / max mm)",
                f"{num(get(sd, 'osc_tracking.pos_err_mm.mean'), '{:.1f}')} / {num(get(sd, 'osc_tracking.pos_err_mm.max'), '{:.1f}')}",
                "", "sim_driver"))
    out.append(("ROS lockstep / in-process wall time, no cameras / two cameras (best runs)",
                f"{num(get(sd, 'overhead_ratio_no_cameras'))} / {num(get(sd, 'overhead_ratio_cameras'))}",
                "goal <= 1.5", "sim_driver"))
    out.append(("the same, median of back-to-back pairs",
                f"{num(get(sd, 'overhead_ratio_paired_median_no_cameras'))} / "
                f"{num(get(sd, 'overhead_ratio_paired_median_cameras'))}", "goal <= 1.5", "sim_driver"))
    out.append(("mock_driver start-up, wall / CPU (median of 5)",
                f"{num(get(sd, 'mock_driver_startup.wall_s_median'))} / {num(get(sd, 'mock_driver_startup.cpu_s_median'))} s",
                "goal < 1 s", "sim_driver"))
    out.append(("recorder messages lost (recorder vs null subscriber)",
                f"{get(rt, 'recorder.lost_total', 'not run')} vs "
                f"{(get(rt, 'baseline_null_subscriber.lost./camera/front/points') or 0) + (get(rt, 'baseline_null_subscriber.lost./joint_states') or 0) if rt else 'not run'}",
                "goal 0", "recorder_throughput"))
    out.append(("recorder write rate", f"{num(get(rt, 'recorder.bag_mb_per_s'), '{:.0f}')} MB/s", "", "recorder_throughput"))
    return out


def rows() -> list[tuple[str, str, str, str]]:
    dg, so = load("datagen"), load("source_demos")
    out = generation_rows(dg) + _datagen_and_hsp_rows(dg) + _planning_rows(load("ik"), load("planning"))
    out += _perception_rows(load("perception")) + _sim_and_recorder_rows(load("sim_driver"), load("recorder_throughput"))
    out += distributed_rows(load("distributed"))
    tasks = get(so, "tasks", {}) or {}
    out.append(("source demos replayed open-loop", ", ".join(f"{t} {v.get('successes')}/{v.get('demos')}" for t, v in tasks.items())
                or "not run", "goal >= 9/10 per task", "source_demos"))
    return out


def distributed_rows(d: dict) -> list[tuple[str, str, str, str]]:
    """Issue 21's figures: the 48-attempt Square D0 cells, mean over the seeds run (summary)."""
    sm = get(d, "summary", {}) or {}

    def g(mode, w, field):
        return get(sm, f"{mode}/w{w}/Square/D0/estimate/n48.{field}.mean")

    if not sm:
        return []
    return [
        ("Ray efficiency at 2 workers, in-process / graph (Square D0, 48 attempts, "
         f"{len(get(sm, 'graph/w2/Square/D0/estimate/n48.seeds') or [])} seeds)",
         f"{pct(g('in_process', 2, 'efficiency'))} / {pct(g('graph', 2, 'efficiency'))} (graph seeds "
         f"{pct(get(sm, 'graph/w2/Square/D0/estimate/n48.efficiency.min'))}-"
         f"{pct(get(sm, 'graph/w2/Square/D0/estimate/n48.efficiency.max'))})",
         "goal >= 85% (2 cores: a graph worker keeps 1.1-1.2 busy)", "distributed"),
        ("Ray overhead per attempt, in-process / graph (2 workers)",
         f"{pct(g('in_process', 2, 'ray_overhead_share'))} / {pct(g('graph', 2, 'ray_overhead_share'))}",
         "goal <= 5%", "distributed"),
        ("demos/h per busy core, graph mode with estimated poses, 1 / 2 workers",
         f"{num(g('graph', 1, 'demos_per_hour_per_busy_core'), '{:.0f}')} / "
         f"{num(g('graph', 2, 'demos_per_hour_per_busy_core'), '{:.0f}')}",
         "MimicGen ~100 (CPU), Isaac Lab Mimic SkillGen 500-670 (RTX GPU)", "distributed"),
    ] + _cancel_rows(d)


def _cancel_rows(d: dict) -> list[tuple[str, str, str, str]]:
    """The worst seed of each mode's cancel cells: workers stopped, in attempts of the same run."""
    worst = {}
    for key, c in d.get("cells", {}).items():
        if key.startswith("cancel/") and c.get("workers_stopped_in_attempts") is not None:
            worst.setdefault(c["mode"], []).append(c["workers_stopped_in_attempts"])
    if not worst:
        return []
    val = " / ".join(f"{max(worst[m]):.2f}" if m in worst else "not run" for m in ("in_process", "graph"))
    n = max(len(v) for v in worst.values())
    return [(f"Ray cancel: workers stopped, in attempts, in-process / graph (worst of {n} seeds)", val,
             "goal <= 1 attempt", "distributed")]


PROFILE_LABEL = {"paper": "paper's algorithm", "skillgen_ros": "ours (skillgen_ros)"}


def _cells(dg: dict) -> list[dict]:
    """Profiled cells only: cells measured before profiles (and the faithful MimicGen) are not shown."""
    return [c for c in dg.get("cells", []) if "profile" in c]


def _cell_set(part: str, cells: list[str]) -> str:
    """Which cells an average covers, named by their tasks ("Square/Coffee D0-D2 cells run")."""
    from bench.datagen.summary import CORE_TASKS

    if part == "clutter":
        return "clutter cells"
    tasks = [t for t in CORE_TASKS if any(c.split()[0] == t for c in cells)] or list(CORE_TASKS)
    if len(cells) == 3 * len(CORE_TASKS):
        return f"the paper's {len(cells)} variants"
    return f"{'/'.join(tasks)} D0-D2 cells run"


def generation_rows(dg: dict) -> list[tuple[str, str, str, str]]:
    """Success averages over cells both sides have, each beside the paper's mean over those cells."""
    from bench.datagen.source_digest import is_stale
    from bench.datagen.summary import cell_key, cells_run, summarize

    cells = _cells(dg)
    s = summarize(cells) if cells else {}
    stale = {(f"{c['task']} {c['variant']}",) + cell_key(c)[2:] for c in cells if is_stale(c)}
    out = []
    for prof in ("paper", "skillgen_ros"):
        for key in ("skillgen", "mimicgen", "skillgen+IA"):
            if prof != "paper" and key == "mimicgen":
                continue  # the same runs as under the paper profile
            for part in ("core", "clutter"):
                g = get(s, f"{prof}.{key}.{part}", {}) or {}
                n = len(g.get("cells", []))
                what = _cell_set(part, g.get("cells", []))
                k = sum((name, key, prof) in stale for name in g.get("cells", []))
                ran = cells_run(cells, prof, key, part)  # a method/part the paper has no number for still ran
                unpaired = f"{ran} cells run; the paper has none of them" if ran else "not run"
                ours = unpaired if g.get("ours") is None else \
                    f"{g['ours']:.1f}% ({n} cells{f', {k} of them {STALE_MARK}' if k else ''})"
                paper = "" if g.get("paper") is None else f"{g['paper']:.1f}% (same {n} cells)"
                out.append((f"generation success, {key}, {PROFILE_LABEL[prof]}, {what}", ours, paper, "datagen"))
    for prof in ("paper", "skillgen_ros"):
        m = get(s, f"{prof}.d1_d2_margin", {}) or {}
        ours = ("not run" if m.get("margin") is None else
                f"{m['skillgen']:.1f} vs {m['mimicgen']:.1f} ({m['margin']:+.1f})")
        out.append((f"skillgen vs mimicgen, Square/Threading/NutAssembly D1-D2, {PROFILE_LABEL[prof]}", ours,
                    "80.1 vs 32.4 (+47.7)", "datagen"))
        ia = get(s, f"{prof}.skillgen+IA.initiation_candidates", {}) or {}
        if ia.get("attempts"):
            hist = ", ".join(f"{k}: {v}" for k, v in ia["per_skill"].items())
            out.append((f"skillgen+IA initiation candidates used per skill, {PROFILE_LABEL[prof]}",
                        f"{hist}; {ia['attempts_with_retry']}/{ia['attempts']} attempts retried", "paper: 1 (fails at once)",
                        "datagen"))
    return out


STALE_MARK = "†"
STALE_NOTE = (f"{STALE_MARK}: measured on source demos remade since (the cell's recorded digest of bags/<task> is "
              "not today's; bench/datagen/source_digest.py): `bench/datagen/run.py` without --force reruns exactly "
              "these cells.")


def _fmt(c: dict | None) -> tuple[str, str]:
    from bench.datagen.source_digest import is_stale

    if c is None:
        return "", ""
    lo, hi = c["wilson95"]
    paper = c.get("paper_rate")
    mark = f" {STALE_MARK}" if is_stale(c) else ""
    return f"{100 * c['rate']:.1f}% ({100 * lo:.0f}-{100 * hi:.0f}){mark}", "" if paper is None else f"{paper:.1f}%"


def cell_rows() -> list[str]:
    """Per cell: the paper's algorithm beside the paper's number per method, then ours in its own
    columns; core cells, clutter cells and cells the paper does not have in separate tables."""
    from bench.datagen.summary import cell_key, is_clutter, is_core, view

    dg = load("datagen")
    cells = _cells(dg)
    if not cells:
        return []
    paper = {cell_key(c)[:3]: c for c in view(cells, "paper")}
    ours = {cell_key(c)[:3]: c for c in view(cells, "skillgen_ros")}
    out = [f"Per cell ({dg.get('attempts_per_cell')} attempts each, {dg.get('perception')} poses, the same seed "
           f"({dg.get('seed')}) and so the same scenes for every method and profile; ours, Wilson 95% interval, paper). "
           "MimicGen has nothing a profile changes and runs once."]
    head = ("| task | variant | skillgen | paper | mimicgen | paper | skillgen+IA | paper | skillgen, ours | "
            "skillgen+IA, ours |")
    groups = (("Cells the paper has (its Table of data generation rates)", lambda t, v: is_core(t, v)),
              ("Clutter (the paper's clutter table where it has the row)", lambda t, v: is_clutter(v)),
              ("Not in the paper", lambda t, v: not is_core(t, v) and not is_clutter(v)))
    pairs = list(dict.fromkeys((t, v) for t, v, _ in list(paper) + list(ours)))
    for title, pred in groups:
        rows = [(t, v) for t, v in pairs if pred(t, v)]
        if not rows:
            continue
        out += ["", f"{title}:", "", head, "|" + "---|" * 10]
        for t, v in rows:
            row = [t, v]
            for key in ("skillgen", "mimicgen", "skillgen+IA"):
                row += list(_fmt(paper.get((t, v, key))))
            row += [_fmt(ours.get((t, v, key)))[0] for key in ("skillgen", "skillgen+IA")]
            out.append("| " + " | ".join(row) + " |")
    if any(STALE_MARK in line for line in out[1:]):
        out += ["", STALE_NOTE]
    out += ["", "The paper's own averages over its 18 simulation variants (skillgen 75.4%, MimicGen 40.7%, "
            "skillgen+IA 14.7%) are the paper's side of an average above only where it covers 18 cells."]
    return out


def contact_model_rows(stock: dict, pads: dict) -> list[str]:
    """The paper profile's cells on another contact model (bench/datagen/run.py --contact-model) beside the
    same cells on the default model: per cell, then the D1/D2 margin when every margin cell ran on both."""
    from bench.datagen.summary import CORE_TASKS, cell_key, margin

    model = pads.get("contact_model")
    theirs = {cell_key(c): c for c in _cells(pads) if c["profile"] == "paper"}
    if not theirs:
        return []
    ours = {cell_key(c): c for c in _cells(stock) if c["profile"] == "paper"}
    out = ["", f"The paper profile's cells on the `{model}` contact model (core/sim/contact_model.py: robosuite's "
           "finger pads, rigid finger contact, 200 solver iterations; source demos made on it; "
           f"`{model}` beside the default `pybullet` cells above, the same seed and attempts; "
           f"bench/results/datagen_{model}.json):", "",
           f"| task | variant | skillgen, pybullet | skillgen, {model} | paper | mimicgen, pybullet | "
           f"mimicgen, {model} | paper |", "|" + "---|" * 8]
    order = {t: i for i, t in enumerate(CORE_TASKS)}
    for t, v in sorted(dict.fromkeys(k[:2] for k in theirs), key=lambda tv: (order.get(tv[0], len(order)), tv[1])):
        row = [t, v]
        for key in ("skillgen", "mimicgen"):
            a, b = ours.get((t, v, key, "paper")), theirs.get((t, v, key, "paper"))
            row += [_fmt(a)[0], _fmt(b)[0], _fmt(b or a)[1]]
        out.append("| " + " | ".join(row) + " |")
    m, base = margin(list(theirs.values()), "paper"), margin(list(ours.values()), "paper")
    if m["margin"] is not None:
        out.append(f"- skillgen vs mimicgen, Square/Threading/NutAssembly D1-D2: {m['skillgen']:.1f} vs "
                   f"{m['mimicgen']:.1f} ({m['margin']:+.1f}) on `{model}`, {base['skillgen']:.1f} vs "
                   f"{base['mimicgen']:.1f} ({base['margin']:+.1f}) on `pybullet`; paper 80.1 vs 32.4 (+47.7).")
    return out


def render() -> str:
    lines = [START, "", "| measure | ours (current) | paper / anchor | bench/results |", "|---|---|---|---|"]
    lines += [f"| {a} | {b} | {c} | `{DATAGEN if d == 'datagen' else d}.json` |" for a, b, c, d in rows()]
    cells = cell_rows()
    if cells:
        from bench.datagen.gaps import gap_rows

        lines += [""] + cells + gap_rows(_cells(load("datagen")))
        lines += contact_model_rows(load("datagen"), load("datagen_robosuite_pads"))
    from bench.hsp.table import (budget_rows, demos_rows, device_rows, equal_budget_gap_rows, hsp_rows,
                                 observation_rows, reg_target_rows, size_rows, source_demo_rows, termination_rows)

    base = load("hsp")
    hsp = hsp_rows(base)
    if hsp:
        before = load("hsp_absolute_obs")  # the run hsp_budget3x, hsp_h200 and hsp_reg_target continued
        longer, v2, v2_longer = load("hsp_budget3x"), load("hsp_v2"), load("hsp_v2_d2_3x")
        lines += [""] + hsp + observation_rows(before, base) + budget_rows(before, longer)
        lines += equal_budget_gap_rows(before, longer, "bench/results/hsp_budget3x.json")
        lines += size_rows(before, longer, load("hsp_h200")) + reg_target_rows(load("hsp_reg_target"))
        lines += termination_rows(load("hsp_termination_labels"), base)
        lines += demos_rows(base, load("hsp_200demos"))
        lines += source_demo_rows(base, v2)
        lines += budget_rows(v2, v2_longer, "bench/results/hsp_v2_d2_3x.json")
        lines += equal_budget_gap_rows(v2, v2_longer, "bench/results/hsp_v2_d2_3x.json")
        lines += device_rows(base, load("hsp_cuda_hsp"), load("hsp_cuda_bc"))
    lines += ["", END]
    return "\n".join(lines)


def main(argv=None) -> int:
    import argparse

    global DATAGEN
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--datagen", default="datagen", help="bench/results/<NAME>.json for the generation rows")
    ap.add_argument("--print-only", action="store_true", help="print the block, leave README.md alone")
    a = ap.parse_args(argv)
    DATAGEN = a.datagen
    block = render()
    if a.print_only:
        print(block)
        return 0
    readme = ROOT / "README.md"
    text = readme.read_text()
    if START in text:
        text = re.sub(re.escape(START) + ".*?" + re.escape(END), block, text, flags=re.S)
    else:
        text = text.rstrip() + "\n\n" + block + "\n"
    readme.write_text(text)
    print(block)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Rebuild the README's results section from bench/results/*.json (between the results markers).

    .venv/bin/python bench/readme_table.py

Each row: our current number, the paper's or the anchor's, and the benchmark JSON it came from.
Missing results show as "not run".
"""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RES = ROOT / "bench" / "results"
START, END = "<!-- results:start -->", "<!-- results:end -->"


def load(name: str) -> dict:
    p = RES / f"{name}.json"
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


def rows() -> list[tuple[str, str, str, str]]:
    ik, pl, pe = load("ik"), load("planning"), load("perception")
    dg, sd, rt, so = load("datagen"), load("sim_driver"), load("recorder_throughput"), load("source_demos")
    out = []
    s = get(dg, "summary", {})
    for key, paper in (("skillgen", "75.4% (sim avg)"), ("mimicgen", "40.7% (sim avg)"),
                       ("skillgen+IA", "14.7% (sim avg)"), ("replay_noise", "see paper App. Replay-Noise")):
        out.append((f"generation success, {key}, all cells", pct(get(s, f"{key}.all")), paper, "datagen"))
    out.append(("generation success, skillgen D2 avg", pct(get(s, "skillgen.D2")), "49-87% (paper D2)", "datagen"))
    out.append(("generation success, mimicgen D2 avg", pct(get(s, "mimicgen.D2")), "4-32% (paper D2)", "datagen"))
    out.append(("generation success, skillgen clutter avg", pct(get(s, "skillgen.clutter")), "49-72%", "datagen"))
    out.append(("generation success, mimicgen clutter avg", pct(get(s, "mimicgen.clutter")), "4-16.5%", "datagen"))
    out.append(("successful demos / hour / core, Square D0 low-dim",
                num(get(dg, "throughput_lowdim.successes_per_hour_per_core"), "{:.0f}"),
                "goal 1500; MimicGen ~100 (CPU); Isaac Lab SkillGen 500-670 (GPU)", "datagen"))
    out.append(("successful demos / hour / core, with 84x84 images",
                num(get(dg, "throughput_images.successes_per_hour_per_core"), "{:.0f}"), "", "datagen"))
    out.append(("graph / in-process time per attempt (median of back-to-back pairs)",
                num(get(dg, "graph_overhead.ratio_graph_to_in_process")),
                "goal <= 1.5", "datagen"))
    out.append(("success with estimated vs ground-truth poses, Square D1",
                f"{pct(get(dg, 'perception_estimate.rate'))} vs {pct(get(dg, 'perception_ground_truth.rate'))}", "",
                "datagen"))
    out.append(("IK solve rate (TRAC-IK protocol, 10k)", pct(get(ik, "ours.solve_rate")),
                "TRAC-IK 99.70%, KDL 61.77%", "ik"))
    out.append(("IK mean / median time", f"{num(get(ik, 'ours.mean_ms'))} / {num(get(ik, 'ours.median_ms'))} ms",
                "TRAC-IK 0.38 ms mean (C++)", "ik"))
    out.append(("planning success, point cloud", pct(get(pl, "results.point_cloud.success_rate")), "goal >= 99%",
                "planning"))
    out.append(("planning median / p95, point cloud",
                f"{ms(get(pl, 'results.point_cloud.time_median_s'))} / {ms(get(pl, 'results.point_cloud.time_p95_s'))}",
                "cuRobo 31 ms (GPU), VAMP 35 us, MoveIt RRT-Connect 100-200 ms", "planning"))
    out.append(("planned paths truly collision-free", pct(get(pl, "results.point_cloud.collision_free_fraction")),
                "must be 100%", "planning"))
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
    tasks = get(so, "tasks", {}) or {}
    out.append(("source demos replayed open-loop", ", ".join(f"{t} {v.get('successes')}/{v.get('demos')}" for t, v in tasks.items())
                or "not run", "goal >= 9/10 per task", "source_demos"))
    return out


def cell_rows() -> list[str]:
    """Per task and variant: ours beside the paper's cell (bench/results/datagen.json)."""
    dg = load("datagen")
    if not dg:
        return []
    by = {(c["task"], c["variant"], c["method"] + ("+IA" if c["augment"] else "")): c for c in dg["cells"]}
    out = [f"Per cell ({dg.get('attempts_per_cell')} attempts each, {dg.get('perception')} poses; "
           "ours, Wilson 95% interval, paper):", "",
           "| task | variant | skillgen | paper | mimicgen | paper | skillgen+IA | paper |", "|---|---|---|---|---|---|---|---|"]
    for task, variant in dict.fromkeys((t, v) for t, v, _ in by):
        row = [task, variant]
        for m in ("skillgen", "mimicgen", "skillgen+IA"):
            c = by.get((task, variant, m))
            if c is None:
                row += ["", ""]
                continue
            lo, hi = c["wilson95"]
            row += [f"{100 * c['rate']:.1f}% ({100 * lo:.0f}-{100 * hi:.0f})",
                    "" if c.get("paper_rate") is None else f"{c['paper_rate']:.1f}%"]
        out.append("| " + " | ".join(row) + " |")
    return out


def render() -> str:
    lines = [START, "", "| measure | ours (current) | paper / anchor | bench/results |", "|---|---|---|---|"]
    lines += [f"| {a} | {b} | {c} | `{d}.json` |" for a, b, c, d in rows()]
    cells = cell_rows()
    if cells:
        lines += [""] + cells
    lines += ["", END]
    return "\n".join(lines)


def main() -> int:
    readme = ROOT / "README.md"
    text = readme.read_text()
    block = render()
    if START in text:
        text = re.sub(re.escape(START) + ".*?" + re.escape(END), block, text, flags=re.S)
    else:
        text = text.rstrip() + "\n\n" + block + "\n"
    readme.write_text(text)
    print(block)
    return 0


if __name__ == "__main__":
    sys.exit(main())

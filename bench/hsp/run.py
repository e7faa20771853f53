"""bench/hsp: Hybrid Skill Policies vs the MimicGen BC-RNN baseline, on the paper's protocol (issue 23, part 3).

Per cell (task, variant): generate N demos (default 1000) with skillgen + initiation augmentation
(t = 0.08 m, r = 80 deg) for HSP and N with MimicGen for the baseline; train one HSP network set
(pi, T + Class head, Reg I) on the skillgen data, shared by HSP-TAMP, HSP-Class and HSP-Reg (pi is
trained once), and one BC-RNN-GMM on every step of the MimicGen data; every `--chunk-steps` training
steps evaluate the checkpoint with `--rollouts` (50) rollouts per method on held-out reset seeds
(core/deploy/seeds.py) and keep each method's best checkpoint, as the paper reports "the
best-performing policy". Every cell reports 95% Wilson intervals beside the paper's numbers.

Budgets: a network trains until `--budget-steps` (robomimic's 200k by default) or `--budget-minutes`
of training wall time (checked at chunk ends; evaluation time excluded), whichever comes first.
On these 2-core CPUs one BC-RNN-GMM step at robomimic's sizes is ~100 ms (bench/results/hsp_timing.json),
so CPU runs use a time budget and may use smaller networks (--hidden, --mlp-hidden), both recorded in the JSON.

Results go to --out (bench/results/hsp.json) after every dataset shard, training chunk and
evaluation, so an interrupted run redoes only what is unfinished: rerun the same command.
Datasets and checkpoints live under --work (out/bench_hsp, not in git).

    # the paper's cells on CPU, low-dim observations (hours; resumable). Square D1 ran with
    # --budget-minutes 25, which gave 13,500 steps; the other cells train those steps, so that the
    # machine's load cannot change how far a network trains (the minutes are checked at chunk ends)
    .venv/bin/python bench/hsp/run.py --budget-steps 13500 --chunk-steps 4500
    # the budget's cost on v2 data (Square D2): its HSP networks trained on from hsp_v2.json's 13.5k last.pt
    .venv/bin/python bench/hsp/run.py --cells Square/D2 --methods HSP-TAMP HSP-Class HSP-Reg --budget-steps 40500 \
        --chunk-steps 4500 --eval-workers 2 --work out/bench_hsp_v2 --datasets-from bench/results/hsp_v2.json \
        --out bench/results/hsp_v2_d2_3x.json
    # ... and its MimicGen BC to the same steps (its own --out, then merged beside the HSP methods)
    .venv/bin/python bench/hsp/run.py --cells Square/D2 --methods MimicGen-BC --budget-steps 40500 --chunk-steps 4500 \
        --eval-workers 2 --work out/bench_hsp_v2 --datasets-from bench/results/hsp_v2.json \
        --out bench/results/hsp_v2_d2_bc_3x.json
    .venv/bin/python bench/hsp/run.py --cells Square/D2 --methods MimicGen-BC --budget-steps 40500 --chunk-steps 4500 \
        --work out/bench_hsp_v2 --merge-from bench/results/hsp_v2_d2_bc_3x.json --out bench/results/hsp_v2_d2_3x.json
    # robomimic's full budget where a GPU is lent
    .venv/bin/python bench/hsp/run.py --device cuda --budget-steps 200000 --out bench/results/hsp_cuda.json
    # the budget's cost on one cell (Square D1): the budget vs 3x
    .venv/bin/python bench/hsp/run.py --cells Square/D1 --budget-minutes 75 --out bench/results/hsp_budget3x.json
    # a smaller LSTM on the same data, evaluated at the same steps (its own --out; checkpoints in net_hsp_1000_h200)
    .venv/bin/python bench/hsp/run.py --cells Square/D1 --methods HSP-Class --hidden 200 --budget-steps 18000 \
        --chunk-steps 4500 --datasets-from bench/results/hsp.json --out bench/results/hsp_h200.json
    # the data-scaling row: Square D2, HSP-Class, 200 demos
    .venv/bin/python bench/hsp/run.py --cells Square/D2 --methods HSP-Class --demos 200 --out bench/results/hsp_200demos.json
    # two processes on 2 cores (--threads 1 each): the HSP methods into hsp.json, the baseline beside it, then merged
    .venv/bin/python bench/hsp/run.py --cells Square/D0 --methods HSP-TAMP HSP-Class HSP-Reg --budget-steps 13500 \
        --chunk-steps 4500 --threads 1
    .venv/bin/python bench/hsp/run.py --cells Square/D0 --methods MimicGen-BC --budget-steps 13500 --chunk-steps 4500 \
        --threads 1 --out bench/results/hsp_bc_part.json
    .venv/bin/python bench/hsp/run.py --cells Square/D0 --methods MimicGen-BC --budget-steps 13500 --chunk-steps 4500 \
        --threads 1 --merge-from bench/results/hsp_bc_part.json
    # one cell's HSP part in a fresh 3 h session on 2 cores (out/ does not outlive a session): generation
    # shards and each checkpoint's rollouts side by side; the data and the summaries are a single process's
    .venv/bin/python bench/hsp/run.py --cells NutAssembly/D1 --methods HSP-TAMP HSP-Class HSP-Reg \
        --budget-steps 13500 --chunk-steps 4500 --gen-workers 2 --eval-workers 2
    # after a fix in deployment: evaluate the kept checkpoints again (the training records stay)
    .venv/bin/python bench/hsp/run.py --cells Square/D1 --methods HSP-TAMP --reevaluate "TAMP goal fix"
    # smoke (seconds of training, 2 rollouts)
    .venv/bin/python bench/hsp/run.py --cells Square/D0 --demos 3 --rollouts 2 --chunk-steps 5 --budget-steps 10 \
        --hidden 32 --mlp-hidden 32 --work /tmp/bench_hsp_smoke --out /tmp/bench_hsp_smoke/hsp.json
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.hsp import shards  # noqa: E402
from bench.hsp.evaluation import evaluate_modes  # noqa: E402
from bench.hsp.results import (CELLS, METHODS, MODE, NETWORK, PAPER, Store,  # noqa: E402,F401
                               merge_from, summary, update_table)
from bench.machine import cpu_model  # noqa: E402


def rerun_command(cell: str, a) -> str:
    keep = [f"--cells {cell}", f"--demos {a.demos}", f"--rollouts {a.rollouts}", f"--seed {a.seed}",
            f"--budget-steps {a.budget_steps}", f"--chunk-steps {a.chunk_steps}", f"--device {a.device}",
            f"--hidden {a.hidden}", f"--mlp-hidden {' '.join(map(str, a.mlp_hidden))}", f"--hsp-data {a.hsp_data}",
            f"--work {a.work}", f"--out {os.path.relpath(a.out, ROOT)}"]
    if a.budget_minutes:
        keep.append(f"--budget-minutes {a.budget_minutes}")
    if a.threads:
        keep.append(f"--threads {a.threads}")
    if tuple(a.methods) != METHODS:  # a part run (the baseline beside the HSP methods, a longer HSP run)
        keep.append(f"--methods {' '.join(a.methods)}")
    if a.datasets_from:  # without it a rerun would generate its own datasets into the same --work
        keep.append(f"--datasets-from {os.path.relpath(a.datasets_from, ROOT)}")
    return ".venv/bin/python bench/hsp/run.py " + " ".join(keep)


def make_dataset(store: Store, cell: str, network: str, a) -> str:
    """N successful demos in shards of attempts (resumable per shard; --gen-workers side by side: shards.py),
    merged in attempt order."""
    from skillgen_ros.core.dataset.hdf5 import merge_datasets

    task, variant = cell.split("/")
    method, augment = ("skillgen", a.hsp_data == "ia") if network == "hsp" else ("mimicgen", False)
    root = Path(a.work) / cell.replace("/", "_") / f"data_{network}_{a.demos}"
    rec = store.cell(cell)["datasets"].setdefault(network, {"method": method, "augment": augment, "shards": []})
    merged = root / "demo.hdf5"
    if rec.get("path") and merged.exists():
        return str(merged)

    def job_of(first: int, attempts: int, want: int, out: str) -> shards.ShardJob:
        return shards.ShardJob(task, variant, method, augment, a.seed, first, attempts, want, out)

    files = shards.generate(rec["shards"], root, job_of, a.demos, a.shard, a.gen_workers, a.max_attempts_factor,
                            store.save)
    merged.unlink(missing_ok=True)
    merge_datasets(files, str(merged), keep=shards.first_n_keep(files, a.demos))
    att = sum(s["attempts"] for s in rec["shards"])
    ok = sum(s["successes"] for s in rec["shards"])  # a parallel batch may overshoot: the merge keeps a.demos
    rec.update(path=str(merged), demos=min(ok, a.demos), attempts=att, generation_rate=ok / att if att else 0.0)
    store.save()
    return str(merged)


def _copy(src: Path, dst: Path) -> None:
    """Copy a checkpoint atomically: another process (retrain_reg, a second run) may be reading dst."""
    if src.resolve() == dst.resolve():
        return
    tmp = dst.with_name(dst.name + ".tmp")
    shutil.copyfile(src, tmp)
    os.replace(tmp, dst)


def evaluate_methods(store: Store, cell: str, network: str, ckpt: Path, step: int, methods, a) -> None:
    from skillgen_ros.core.deploy import evaluate
    from skillgen_ros.core.learning.checkpoint import load_hsp

    task, variant = cell.split("/")
    c = store.cell(cell)
    done, t0, policy = {}, time.time(), None
    if a.eval_workers > 1:  # every method's rollouts side by side (evaluation.py); the same summaries
        done = evaluate_modes(str(ckpt), task, variant, [MODE[m] for m in methods], a.rollouts, a.seed, a.device,
                              a.eval_workers)
    else:
        policy = load_hsp(str(ckpt), device=a.device, expect_task=task)  # pi shared by the HSP methods
    for m in methods:
        t = time.time()
        s = done.get(MODE[m]) or evaluate(str(ckpt), task, variant, MODE[m], a.rollouts, a.seed, device=a.device,
                                          policy=policy)
        rec = {**s.to_json(), "step": step, "eval_seconds": time.time() - (t0 if done else t),
               "cpu_model": cpu_model()}
        if done:
            rec["eval_workers"] = a.eval_workers  # eval_seconds: the methods' shared wall time
        rec.pop("reset_seeds", None)
        mrec = c["methods"].setdefault(m, {"evals": [], "paper": PAPER.get(cell, {}).get(m)})
        mrec["evals"].append(rec)
        if "best" not in mrec or rec["success_rate"] > mrec["best"]["success_rate"]:
            mrec["best"] = rec
            _copy(ckpt, ckpt.parent / f"best_{m}.pt")
        print(f"  {cell} {m} @ step {step}: {s.line()}", flush=True)
        store.save()


def net_dir(cell: str, network: str, a) -> Path:
    """A network's checkpoints; sizes other than robomimic's get their own folder beside the same data."""
    size = "" if a.hidden == 400 else f"_h{a.hidden}"
    size += "" if list(a.mlp_hidden) == [1024, 1024] else "_m" + "x".join(map(str, a.mlp_hidden))
    return Path(a.work) / cell.replace("/", "_") / f"net_{network}_{a.demos}{size}"


def train_network(store: Store, cell: str, network: str, dataset: str, methods, a) -> None:
    """Train in chunks (the trainer resumes from last.pt), evaluating each chunk's checkpoint."""
    from skillgen_ros.core.learning.config import NetworkConfig, TrainConfig
    from skillgen_ros.core.learning.trainer import TrainRequest, train

    out = net_dir(cell, network, a)
    rec = store.cell(cell)["networks"].setdefault(network, {"train_seconds": 0.0, "steps": 0, "finished": False})
    if rec["steps"] and not (out / "last.pt").exists():   # recorded by a machine whose out/ is gone: start over
        print(f"  {cell} {network}: {out / 'last.pt'} is gone; training again from step 0", flush=True)
        rec.update(train_seconds=0.0, steps=0, timed_steps=0, finished=False)
        for m in methods:
            lost = store.cell(cell)["methods"].pop(m, None)
            if lost:
                store.cell(cell).setdefault("lost_evals", {})[m] = lost.get("evals", [])
    rec.setdefault("timed_steps", rec["steps"])  # records written before timed_steps timed all their steps
    rec.update(dataset=dataset, hidden=a.hidden, mlp_hidden=list(a.mlp_hidden), budget_steps=a.budget_steps,
               budget_minutes=a.budget_minutes)
    net = NetworkConfig(rnn_hidden=a.hidden, mlp_hidden=tuple(a.mlp_hidden))
    epochs = max(1, a.budget_steps // a.steps_per_epoch)
    tc = TrainConfig(epochs=epochs, steps_per_epoch=a.steps_per_epoch, eval_every=0, device=a.device, seed=a.seed,
                     threads=a.threads)
    _evaluate_unevaluated(store, cell, network, out / f"step_{rec['steps']:06d}.pt", rec["steps"], methods, a)
    before = _trained_steps(out / "last.pt")  # where the next chunk resumes; then each chunk's own end
    while not rec["finished"] and not (a.budget_minutes and rec["train_seconds"] >= 60 * a.budget_minutes):
        t = time.time()
        r = train(TrainRequest(dataset=dataset, output_dir=str(out), network=net, train=tc,
                               resume=(out / "last.pt").exists(), stop_after=a.chunk_steps, progress=False))
        rec["train_seconds"] += time.time() - t
        rec["steps"], rec["finished"] = int(r.config.step), bool(r.finished or r.config.step >= a.budget_steps)
        # timed_steps: the steps this record's train_seconds cover (a network resumed from another run's
        # last.pt under a new --out starts its record at 0 s but at that run's step)
        rec["timed_steps"] += int(r.config.step) - before
        before = int(r.config.step)
        rec["ms_per_train_step"] = 1000 * rec["train_seconds"] / max(1, rec["timed_steps"])
        # the file's "machine" is the last run's; a network resumed on another machine names each it trained on
        cpu = cpu_model()
        if cpu not in rec.setdefault("cpu_models", []):
            rec["cpu_models"].append(cpu)
        kept = out / f"step_{int(r.config.step):06d}.pt"  # every chunk's checkpoint stays: --reevaluate reads them
        _copy(Path(r.last_path), kept)
        store.save()
        evaluate_methods(store, cell, network, kept, int(r.config.step), methods, a)


def _trained_steps(last: Path) -> int:
    """The step a resumed training starts from (0 without a last.pt)."""
    from skillgen_ros.core.learning.checkpoint import read_checkpoint

    return int(read_checkpoint(last)[0].step) if last.exists() else 0


def _evaluate_unevaluated(store: Store, cell: str, network: str, kept: Path, step: int, methods, a) -> None:
    """A run stopped between a chunk's training and its evaluation left `step` unevaluated: evaluate it now,
    before training goes on (or when training had already finished), so no chunk's result is lost."""
    done = store.cell(cell)["methods"]
    missing = [m for m in methods if step not in {e["step"] for e in done.get(m, {}).get("evals", [])}]
    if step and missing and kept.exists():
        print(f"  {cell} {network}: step {step} was trained but not evaluated; evaluating {missing}", flush=True)
        evaluate_methods(store, cell, network, kept, step, missing, a)


def kept_checkpoints(folder: Path, max_step: int) -> dict[int, Path]:
    """The network's checkpoints on disk by training step (step_*.pt, best_*.pt, last.pt), up to max_step:
    a longer run that resumed in the same --work (the 3x budget) leaves later ones beside them."""
    from skillgen_ros.core.learning.checkpoint import read_checkpoint

    found: dict[int, Path] = {}
    for f in sorted(folder.glob("step_*.pt")) + sorted(folder.glob("best_*.pt")) + [folder / "last.pt"]:
        if f.exists():
            step = int(read_checkpoint(f)[0].step)
            if step <= max_step:
                found.setdefault(step, f)
    return dict(sorted(found.items()))


def reevaluate_cell(store: Store, cell: str, a) -> None:
    """Evaluate the kept checkpoints again with the current deploy code (after a fix in it): the selected
    methods' evals and best are replaced; the training records stay."""
    c = store.cell(cell)
    methods = [m for m in a.methods if m in METHODS]
    for network in ("hsp", "bc"):
        mine = [m for m in methods if NETWORK[m] == network]
        nrec = c["networks"].get(network)
        if not mine or not nrec:
            continue
        folder = net_dir(cell, network, a)
        ckpts = kept_checkpoints(folder, int(nrec["steps"]))
        if not ckpts:
            print(f"  {cell} {network}: no kept checkpoint in {folder}", flush=True)
            continue
        for m in mine:
            old = c["methods"].pop(m, None) or {}
            first = old.get("reevaluated", {}).get("replaced_evals")  # the training run's own evals, kept once
            c["methods"][m] = {"evals": [], "paper": PAPER.get(cell, {}).get(m),
                               "reevaluated": {"reason": a.reevaluate, "steps": sorted(ckpts),
                                               "replaced_evals": first if first is not None else old.get("evals", [])}}
        # copy them all first: evaluate_methods rewrites best_*.pt, which may be where a later step lives
        copies = {}
        for step, path in ckpts.items():
            copies[step] = folder / f"reeval_{step:06d}.pt"
            _copy(path, copies[step])
        for step, tmp in copies.items():
            evaluate_methods(store, cell, network, tmp, step, mine, a)
            _copy(tmp, folder / f"step_{step:06d}.pt")  # kept under its step from now on
            tmp.unlink()
    update_table(c, METHODS)
    store.save()


def run_cell(store: Store, cell: str, a) -> None:
    methods = [m for m in a.methods if m in METHODS]
    c = store.cell(cell)
    c["rerun"] = rerun_command(cell, a)
    c["paper"] = PAPER.get(cell, {})
    for network in ("hsp", "bc"):
        mine = [m for m in methods if NETWORK[m] == network]
        if mine:
            dataset = make_dataset(store, cell, network, a)
            train_network(store, cell, network, dataset, mine, a)
    update_table(c, METHODS)  # every method the cell has: a run of some methods keeps the others' rows
    store.save()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cells", nargs="+", default=list(CELLS))
    p.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    p.add_argument("--demos", type=int, default=1000, help="generated demos per dataset (paper: 1000)")
    p.add_argument("--rollouts", type=int, default=50, help="evaluation rollouts per checkpoint (paper: 50)")
    p.add_argument("--seed", type=int, default=0, help="generation run seed and evaluation seed")
    p.add_argument("--hsp-data", default="ia", choices=["ia", "plain"],
                   help="HSP's shared network trains on skillgen+IA data (ia, the issue's choice) or plain skillgen")
    p.add_argument("--budget-steps", type=int, default=200_000, help="training steps per network (robomimic: 200k)")
    p.add_argument("--budget-minutes", type=float, default=0.0, help="training wall minutes per network (0: none)")
    p.add_argument("--chunk-steps", type=int, default=5000, help="steps between evaluations (robomimic: 50 epochs x 100)")
    p.add_argument("--steps-per-epoch", type=int, default=100)
    p.add_argument("--hidden", type=int, default=400, help="LSTM size (robomimic 400; smaller must be disclosed)")
    p.add_argument("--mlp-hidden", type=int, nargs="+", default=[1024, 1024])
    p.add_argument("--device", default="cpu")
    p.add_argument("--threads", type=int, default=0, help="torch CPU threads (0: torch's default; 1 when two runs share 2 cores)")
    p.add_argument("--shard", type=int, default=100, help="demos per generation shard (the resume granularity)")
    p.add_argument("--max-attempts-factor", type=int, default=5)
    p.add_argument("--eval-workers", type=int, default=1,
                   help="evaluation rollouts side by side (processes); the same summaries (bench/hsp/evaluation.py)")
    p.add_argument("--gen-workers", type=int, default=1,
                   help="generation shards side by side (processes); the dataset is the same (bench/hsp/shards.py)")
    p.add_argument("--work", default="out/bench_hsp", help="datasets and checkpoints (not in git)")
    p.add_argument("--out", default=str(ROOT / "bench" / "results" / "hsp.json"))
    p.add_argument("--datasets-from", metavar="JSON", default="",
                   help="reuse the datasets another results file generated (a new --out for another size or budget)")
    p.add_argument("--reevaluate", metavar="REASON", default="",
                   help="evaluate the kept checkpoints of the cells' methods again (after a deploy fix; REASON is recorded)")
    p.add_argument("--merge-from", metavar="JSON", default="",
                   help="copy --methods' records for --cells from another results file (the same protocol run as a "
                        "second process, e.g. MimicGen-BC beside the HSP methods) into --out, then stop")
    a = p.parse_args(argv)
    from skillgen_ros.core.tasks import TASK_NAMES

    unknown = [c for c in a.cells if c.split("/")[0] not in TASK_NAMES]
    if unknown:
        p.error(f"unknown cells {unknown}; e.g. {CELLS[0]}")
    Path(a.work).mkdir(parents=True, exist_ok=True)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    if a.merge_from:
        return merge_from(Path(a.merge_from), Path(a.out), a)
    store = Store(Path(a.out), a)
    if a.datasets_from:  # another network size or budget on the same generated data
        other = json.loads(Path(a.datasets_from).read_text()).get("cells", {})
        for cell in a.cells:
            if cell in other and not store.cell(cell)["datasets"]:
                store.cell(cell)["datasets"] = other[cell].get("datasets", {})
    for cell in a.cells:
        print(f"== {cell}", flush=True)
        (reevaluate_cell if a.reevaluate else run_cell)(store, cell, a)
        store.data["summary"] = summary(store.data)
        store.save()
    print(json.dumps(store.data["summary"], indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""bench/hsp on a lent GPU: train there, evaluate here (issue 23: the budget these CPUs cannot give).

A lent device machine has torch with CUDA but no pybullet, OMPL, mcap or ROS, 15 minutes of device
time per session, and 64 MiB each way (/work/.library/device/README.md). So the work splits in three:

  pack      (here)   each cell's generated datasets, reduced to what the trainer reads (read_demos and
                     dataset_info: four obs keys, actions, labels, attrs, the mask/train + mask/valid
                     split) as float32 (labels exact), byte-shuffled and lzma-compressed: 14.6 MiB for
                     Square D2's 1000 HSP demos (211 MB as HDF5); plus HSP-Class's class count;
  train     (there)  rebuild each HDF5, train every dataset at once (one process each) with the same
                     trainer, network sizes and seed as bench/hsp/run.py until a wall-clock deadline,
                     in --chunk-steps chunks (each a resume from last.pt); keep each chunk's
                     checkpoint weights-only (Adam's state does not act: 16.6 MiB instead of 51);
                     return the last and middle ones first, up to 58 MiB, as a tar in 15 MiB pieces,
                     plus train_log.json (per chunk: steps, seconds, losses);
  evaluate  (here)   join the pieces and evaluate every returned checkpoint with run.py's
                     evaluate_methods (50 held-out rollouts per method, on CPU) into --out.

Training on float32-rounded inputs moves the obs statistics in the 7th digit; the checkpoint records
the rebuilt file's sha256, not the original's.

    .venv/bin/python bench/hsp/device.py pack --cells Square/D2 --dest .gpu   # .gpu/ in .git/info/exclude
    # on the device (the run tool, carry [".gpu"]), one call: 2 networks x 8 minutes
    python3 bench/hsp/device.py train --data .gpu --out $OUT --deadline-s 480 --chunk-steps 10000
    .venv/bin/python bench/hsp/device.py evaluate --pieces /work/.device/N --work out/bench_hsp_cuda/runN \
        --out bench/results/hsp_cuda_hsp.json
"""
from __future__ import annotations

import argparse
import json
import lzma
import os
import subprocess
import sys
import tarfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

OBS = ("robot0_eef_pos", "robot0_eef_quat", "robot0_gripper_qpos", "object")  # LOW_DIM_KEYS' stored sources
LABELS = ("mp_step", "source_demo", "initiation_target", "augmented", "skill_index")
PIECE = 15 * 2**20
RETURN_LIMIT = 58 * 2**20  # of the device's 64 MiB back, room for the log


def _shuffled(a: np.ndarray) -> bytes:
    """Byte-plane order (HDF5's shuffle filter): float columns then compress several times better."""
    return np.ascontiguousarray(a).view(np.uint8).reshape(-1, a.dtype.itemsize).T.tobytes()


def _unshuffled(b: bytes, dtype: str, shape: list[int]) -> np.ndarray:
    dt = np.dtype(dtype)
    return np.frombuffer(b, np.uint8).reshape(dt.itemsize, -1).T.copy().view(dt).reshape(shape)


def pack(a) -> int:
    """Per dataset a folder: meta.json (attrs, split, demo lengths, dtypes) and one lzma file per key,
    all demos concatenated. Float arrays are stored as float32 (what the trainer computes in; the
    obs statistics then differ from the float64 file's in the 7th digit), integer labels losslessly."""
    import h5py

    from skillgen_ros.core.learning.config import TrainConfig
    from skillgen_ros.core.learning.data import split_train_valid

    for cell in a.cells:
        for net in a.networks:
            src = Path(a.work) / cell.replace("/", "_") / f"data_{net}_{a.demos}" / "demo.hdf5"
            out = Path(a.dest) / f"{cell.replace('/', '_')}__{net}"
            out.mkdir(parents=True, exist_ok=True)
            # the file's stored split, written now (as the trainer would) if it has none yet
            train, valid = split_train_valid(str(src), TrainConfig().valid_ratio, TrainConfig().seed)
            with h5py.File(src, "r") as f:
                names = sorted(f["data"], key=lambda k: int(k[5:]))
                meta = {"source": str(src), "data_attrs": {k: (v.tolist() if hasattr(v, "tolist") else v)
                                       for k, v in f["data"].attrs.items()},
                        "mask": {"train": list(train), "valid": list(valid)},
                        "demos": names, "lengths": [int(f["data"][n]["actions"].shape[0]) for n in names],
                        "demo_attrs": [{k: (v.tolist() if hasattr(v, "tolist") else v)
                                        for k, v in f["data"][n].attrs.items()} for n in names], "keys": {}}
                first = f["data"][names[0]]
                keys = [f"obs/{k}" for k in OBS] + ["actions"] + [f"labels/{k}" for k in LABELS if k in first["labels"]]
                for k in keys:
                    arr = np.concatenate([f["data"][n][k][()] for n in names])
                    small = arr.astype(np.float32 if arr.dtype.kind == "f" else np.int32)
                    if arr.dtype.kind != "f" and not np.array_equal(small, arr):
                        raise SystemExit(f"{src} {k}: does not fit int32")
                    # lzma over byte planes of whole columns: 14.6 MiB for Square D2's HSP data, where
                    # h5py's per-demo gzip + shuffle left 65.7 MiB of float64 (over the device's 64 MiB)
                    (out / (k.replace("/", "__") + ".xz")).write_bytes(lzma.compress(_shuffled(small), preset=6))
                    meta["keys"][k] = {"dtype": str(arr.dtype), "stored": str(small.dtype), "shape": list(small.shape)}
            if net == "hsp":  # HSP-Class's classes, counted as the trainer would (bags/ needs mcap: not there)
                from skillgen_ros.core.learning.trainer import count_source_demos
                meta["source_demos"] = count_source_demos(str(ROOT / "bags"), cell.split("/")[0], 1)
            (out / "meta.json").write_text(json.dumps(meta))
            size = sum(p.stat().st_size for p in out.iterdir())
            print(f"{src} -> {out}: {size / 2**20:.1f} MiB", flush=True)
    return 0


def unpack(folder: Path, dest: Path) -> Path:
    """The robomimic-layout HDF5 the trainer reads, rebuilt from a packed folder."""
    import h5py

    meta = json.loads((folder / "meta.json").read_text())
    arrays = {k: _unshuffled(lzma.decompress((folder / (k.replace("/", "__") + ".xz")).read_bytes()), m["stored"],
                             m["shape"]).astype(m["dtype"]) for k, m in meta["keys"].items()}
    ends = np.cumsum(meta["lengths"])
    with h5py.File(dest, "w") as g:
        data = g.create_group("data")
        for k, v in meta["data_attrs"].items():
            data.attrs[k] = v
        for k, v in meta["mask"].items():
            g.create_dataset(f"mask/{k}", data=np.array([n.encode() for n in v], dtype="S"))
        for name, attrs, b, e in zip(meta["demos"], meta["demo_attrs"], ends - np.array(meta["lengths"]), ends):
            h = data.create_group(name)
            for k, v in attrs.items():
                h.attrs[k] = v
            for k, arr in arrays.items():
                h.create_dataset(k, data=arr[b:e])
    return dest


def _train_one(a) -> int:
    """One dataset until the deadline (a child process of `train`)."""
    import torch

    from skillgen_ros.core.learning.checkpoint import load_networks, read_checkpoint, save_checkpoint
    from skillgen_ros.core.learning.config import NetworkConfig, TrainConfig
    from skillgen_ros.core.learning.trainer import TrainRequest, train

    work, keep = Path(a.work_dir), Path(a.keep_dir)
    keep.mkdir(parents=True, exist_ok=True)
    net = NetworkConfig(rnn_hidden=a.hidden, mlp_hidden=tuple(a.mlp_hidden))
    # epochs only set how often last.pt, validation and the loss record are written (batches depend on
    # (seed, step) alone): 1000-step epochs keep a 51 MB save per 100 GPU steps from dominating
    tc = TrainConfig(epochs=a.budget_steps // a.steps_per_epoch, steps_per_epoch=a.steps_per_epoch, eval_every=0,
                     device=a.device, seed=a.seed)
    log = {"dataset": a.dataset, "chunks": [], "device": torch.cuda.get_device_name(0) if a.device == "cuda" else
           "cpu", "torch": torch.__version__}
    t_start = time.time()
    while True:
        t = time.time()
        # num_source_demos: counted by `pack`; counting bags/ needs mcap, which the device lacks
        r = train(TrainRequest(dataset=a.dataset, output_dir=str(work), network=net, train=tc,
                               num_source_demos=a.source_demos, resume=(work / "last.pt").exists(),
                               stop_after=a.chunk_steps, progress=False))
        step = int(r.config.step)
        cfg, sds, _ = read_checkpoint(r.last_path)
        save_checkpoint(keep / f"step_{step:06d}.pt", cfg, load_networks(cfg, sds))  # weights only
        log["chunks"].append({"step": step, "seconds": time.time() - t,
                              "history_tail": cfg.history[-1] if cfg.history else None})
        Path(a.log).write_text(json.dumps(log, indent=1))
        per_chunk = (time.time() - t_start) / len(log["chunks"])
        print(f"{a.dataset}: step {step} after {time.time() - t_start:.0f} s", flush=True)
        if r.finished or time.time() + per_chunk > a.deadline:
            return 0


def _choose(kept: dict[str, list[Path]]) -> list[Path]:
    """Every network's last checkpoint, then its middle one, then the rest latest first (round robin
    over networks) while they fit the return limit: a learning curve, not the last few chunks."""
    def order(v: list[Path]) -> list[Path]:
        first = [v[-1], v[(len(v) - 1) // 2]] if len(v) > 1 else list(v)
        return list(dict.fromkeys(first + list(reversed(v))))

    queues = [order(v) for v in kept.values()]
    chosen, size = [], 0
    while any(queues):
        for q in queues:
            if q:
                p = q.pop(0)
                if size + p.stat().st_size <= RETURN_LIMIT:
                    chosen.append(p)
                    size += p.stat().st_size
    return chosen


def train_all(a) -> int:
    out = Path(a.out)
    deadline = time.time() + a.deadline_s
    procs, sources = {}, {}
    for folder in sorted(p.parent for p in Path(a.data).glob("*/meta.json")):
        name = folder.name
        Path(f"/tmp/hsp_dev/{name}").mkdir(parents=True, exist_ok=True)
        ds = unpack(folder, Path(f"/tmp/hsp_dev/{name}/demo.hdf5"))
        meta = json.loads((folder / "meta.json").read_text())
        classes, sources[name] = a.source_demos or meta.get("source_demos", 0), meta["source"]
        cmd = [sys.executable, __file__, "_one", "--dataset", str(ds), "--work-dir", f"/tmp/hsp_dev/{name}/work",
               "--keep-dir", f"/tmp/hsp_dev/{name}/keep", "--log", f"/tmp/hsp_dev/{name}.json",
               "--deadline", str(deadline), "--chunk-steps", str(a.chunk_steps), "--budget-steps", str(a.budget_steps),
               "--hidden", str(a.hidden), "--mlp-hidden", *map(str, a.mlp_hidden), "--device", a.device,
               "--seed", str(a.seed), "--steps-per-epoch", str(a.steps_per_epoch), "--source-demos", str(classes)]
        procs[name] = subprocess.Popen(cmd)
    codes = {n: p.wait() for n, p in procs.items()}
    kept = {n: sorted(Path(f"/tmp/hsp_dev/{n}/keep").glob("step_*.pt")) for n in procs}
    logs = {n: json.loads(Path(f"/tmp/hsp_dev/{n}.json").read_text()) if Path(f"/tmp/hsp_dev/{n}.json").exists()
            else None for n in procs}
    chosen = _choose(kept)
    tar = Path("/tmp/hsp_dev/checkpoints.tar")
    with tarfile.open(tar, "w") as t:
        for p in chosen:
            t.add(p, arcname=f"{p.parent.parent.name}/{p.name}")
    data = tar.read_bytes()
    for i in range(0, len(data), PIECE):
        (out / f"checkpoints.tar.{i // PIECE:02d}").write_bytes(data[i:i + PIECE])
    (out / "train_log.json").write_text(json.dumps({"exit_codes": codes, "logs": logs, "sources": sources,
                                                    "returned": [f"{p.parent.parent.name}/{p.name}" for p in chosen],
                                                    "kept": {n: [p.name for p in v] for n, v in kept.items()},
                                                    "argv": sys.argv}, indent=1))
    print(json.dumps({"exit_codes": codes, "returned": [str(p) for p in chosen]}), flush=True)
    return 0 if all(c == 0 for c in codes.values()) else 1


def evaluate(a) -> int:
    """Join the pieces, then evaluate each returned checkpoint as bench/hsp/run.py would have."""
    from bench.hsp.results import METHODS, NETWORK, PAPER, Store, update_table
    from bench.hsp.run import evaluate_methods

    pieces = sorted(Path(a.pieces).glob("checkpoints.tar.*"))
    log = json.loads((Path(a.pieces) / "train_log.json").read_text())
    work = Path(a.work)
    work.mkdir(parents=True, exist_ok=True)
    tar = work / "checkpoints.tar"
    tar.write_bytes(b"".join(p.read_bytes() for p in pieces))
    with tarfile.open(tar) as t:
        t.extractall(work, filter="data")
    ns = argparse.Namespace(reevaluate="", rollouts=a.rollouts, seed=a.seed, device="cpu", cells=[], methods=[],
                            datasets_from="", out=a.out, work=str(work), trained_by=log["argv"],
                            evaluated_by=["bench/hsp/device.py", *sys.argv[1:]])
    store = Store(Path(a.out), ns)
    for name in sorted({Path(p).parts[0] for p in log["returned"]}):
        cell = name.split("__")[0].replace("_", "/")
        network = name.split("__")[1]
        methods = [m for m in (a.methods or METHODS) if NETWORK[m] == network]
        c = store.cell(cell)
        c["paper"] = PAPER.get(cell, {})
        dl = log["logs"][name]
        c["networks"][network] = {"device": dl["device"], "torch": dl["torch"], "steps": dl["chunks"][-1]["step"],
                                  "dataset": log.get("sources", {}).get(name, "") + " (packed: float32)",
                                  "train_seconds": sum(ch["seconds"] for ch in dl["chunks"]),
                                  "chunks": [{k: ch[k] for k in ("step", "seconds")} for ch in dl["chunks"]]}
        c["networks"][network]["ms_per_train_step"] = (1000 * c["networks"][network]["train_seconds"]
                                                      / max(1, c["networks"][network]["steps"]))
        # latest first: the budget's end is the number asked for; earlier steps fill in the curve
        steps = sorted((int(Path(p).stem.split("_")[1]) for p in log["returned"] if Path(p).parts[0] == name),
                       reverse=True)
        for step in steps:
            if any(e["step"] == step for m in methods for e in c["methods"].get(m, {}).get("evals", [])):
                continue  # resumable: done in an earlier invocation
            evaluate_methods(store, cell, network, work / name / f"step_{step:06d}.pt", step, methods, ns)
        update_table(c, METHODS)
        store.save()
    return 0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    pk = sub.add_parser("pack")
    pk.add_argument("--cells", nargs="+", default=["Square/D2"])
    pk.add_argument("--networks", nargs="+", default=["hsp", "bc"])
    pk.add_argument("--demos", type=int, default=1000)
    pk.add_argument("--work", default="out/bench_hsp")
    pk.add_argument("--dest", default=".gpu")
    for name in ("train", "_one"):
        t = sub.add_parser(name)
        t.add_argument("--chunk-steps", type=int, default=10000)
        t.add_argument("--budget-steps", type=int, default=200_000, help="robomimic's 200k")
        t.add_argument("--hidden", type=int, default=400)
        t.add_argument("--mlp-hidden", type=int, nargs="+", default=[1024, 1024])
        t.add_argument("--device", default="cuda")
        t.add_argument("--seed", type=int, default=0)
        t.add_argument("--steps-per-epoch", type=int, default=1000, help="bench/hsp/run.py: 100 (robomimic's)")
        t.add_argument("--source-demos", type=int, default=0,
                       help="HSP-Class's classes (default: the count `pack` stored)")
        if name == "train":
            t.add_argument("--data", default=".gpu")
            t.add_argument("--out", default=os.environ.get("OUT", "out/device"))
            t.add_argument("--deadline-s", type=float, default=470)
        else:
            for k in ("--dataset", "--work-dir", "--keep-dir", "--log"):
                t.add_argument(k, required=True)
            t.add_argument("--deadline", type=float, required=True)
    ev = sub.add_parser("evaluate")
    ev.add_argument("--pieces", required=True)
    ev.add_argument("--work", default="out/bench_hsp_cuda")
    ev.add_argument("--out", default=str(ROOT / "bench" / "results" / "hsp_cuda.json"))
    ev.add_argument("--rollouts", type=int, default=50)
    ev.add_argument("--seed", type=int, default=0)
    ev.add_argument("--methods", nargs="*", default=[])
    a = p.parse_args(argv)
    return {"pack": pack, "train": train_all, "_one": _train_one, "evaluate": evaluate}[a.cmd](a)


if __name__ == "__main__":
    sys.exit(main())

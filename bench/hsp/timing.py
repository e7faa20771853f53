"""HSP compute cost on this CPU: one training step of each network, and π + T inference per control step.

Training: one Adam step of the default BC-RNN-GMM (2x400 LSTM, GMM 5 modes, batch 100, sequence
10) and of T (+ HSP-Class head, MLP 2x1024, batch 100), low-dim Square observations, for each
thread count asked. Inference: `HybridSkillPolicy.act` + `.terminated` per 20 Hz control step with
torch.set_num_threads(1) (the issue's goal: <= 5 ms, a 10x margin on 50 ms). Networks are freshly
initialized (cost does not depend on the weights); observations are Square's layout. With
--images the 84x84 front + wrist cameras are added (ResNet-18 per camera and network).

    python bench/hsp/timing.py [--quick] [--images] [--threads 1 2] [--out bench/results/hsp_timing.json]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from bench.machine import machine_info  # noqa: E402

from skillgen_ros.core.learning.config import HSPConfig, NetworkConfig, TrainConfig  # noqa: E402
from skillgen_ros.core.learning.hsp import HybridSkillPolicy  # noqa: E402
from skillgen_ros.core.learning.networks import build_networks  # noqa: E402
from skillgen_ros.core.learning.normalization import ObsStats  # noqa: E402
from skillgen_ros.core.learning.observation import IMAGE_KEYS, LOW_DIM_KEYS  # noqa: E402

SHAPES = {"robot0_eef_pos": (3,), "robot0_eef_quat": (4,), "robot0_gripper_qpos": (2,), "object": (14,),
          "object_to_eef": (14,)}


def square_config(images: bool, net: NetworkConfig) -> HSPConfig:
    img = IMAGE_KEYS if images else ()
    shapes = {**SHAPES, **{k: (84, 84, 3) for k in img}}
    stats = ObsStats({k: (0.0,) * int(np.prod(s)) for k, s in SHAPES.items()},
                     {k: (1.0,) * int(np.prod(s)) for k, s in SHAPES.items()})
    return HSPConfig(task="Square", variant="D1", method="skillgen", skills=("grasp_nut", "place_on_peg"),
                     low_dim_keys=LOW_DIM_KEYS, image_keys=img, obs_shapes=shapes,
                     object_ids=("square_nut", "square_peg"), num_source_demos=10, all_steps=False,
                     has_termination=True, has_class=True, has_reg=False, obs_stats=stats, initiation_norm=None,
                     dataset_sha256="", dataset_path="", train_demos=(), valid_demos=(), network=net)


def _batch(cfg: HSPConfig, lead: tuple[int, ...]) -> dict[str, torch.Tensor]:
    out = {k: torch.randn(*lead, int(np.prod(cfg.obs_shapes[k]))) for k in cfg.low_dim_keys}
    out.update({k: torch.randint(0, 255, (*lead, 84, 84, 3), dtype=torch.uint8) for k in cfg.image_keys})
    return out


def train_step_ms(cfg: HSPConfig, threads: int, steps: int, batch: int) -> dict[str, float]:
    torch.set_num_threads(threads)
    nets = build_networks(cfg)
    seq = cfg.network.seq_length
    pi, term = nets["policy"].train(), nets["termination"].train()
    opt_pi, opt_t = torch.optim.Adam(pi.parameters(), 1e-4), torch.optim.Adam(term.parameters(), 1e-4)
    obs_seq, act = _batch(cfg, (batch, seq)), torch.rand(batch, seq, 7) * 2 - 1
    obs, y, c = _batch(cfg, (batch,)), torch.randint(0, 2, (batch,)), torch.randint(0, 10, (batch,))
    times: dict[str, list[float]] = {"policy": [], "termination": []}
    for i in range(steps + 2):  # two warm-up steps
        t0 = time.perf_counter()
        loss = pi.loss(obs_seq, act)
        opt_pi.zero_grad()
        loss.backward()
        opt_pi.step()
        t1 = time.perf_counter()
        tl, cl = term(obs)
        loss = torch.nn.functional.cross_entropy(tl, y) + torch.nn.functional.cross_entropy(cl, c)
        opt_t.zero_grad()
        loss.backward()
        opt_t.step()
        t2 = time.perf_counter()
        if i >= 2:
            times["policy"].append(t1 - t0)
            times["termination"].append(t2 - t1)
    return {f"{k}_ms_median": 1e3 * float(np.median(v)) for k, v in times.items()}


def inference_ms(cfg: HSPConfig, steps: int) -> dict[str, float]:
    torch.set_num_threads(1)
    p = HybridSkillPolicy(cfg, build_networks(cfg))
    rng = np.random.default_rng(0)
    obs = [{k: (rng.integers(0, 255, s, dtype=np.uint8) if k in cfg.image_keys else rng.normal(size=s))
            for k, s in cfg.obs_shapes.items()} for _ in range(steps + 10)]
    p.start_skill(0)
    dt = []
    for i, o in enumerate(obs):
        t0 = time.perf_counter()
        p.act(o)
        p.terminated(o)
        if i >= 10:
            dt.append(time.perf_counter() - t0)
    dt_ms = 1e3 * np.array(dt)
    return {"pi_plus_T_ms_median": float(np.median(dt_ms)), "pi_plus_T_ms_p95": float(np.percentile(dt_ms, 95)),
            "pi_plus_T_ms_max": float(dt_ms.max()), "steps": steps}


def main(argv=None) -> int:
    a = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    a.add_argument("--quick", action="store_true", help="5 training steps, 100 inference steps")
    a.add_argument("--images", action="store_true")
    a.add_argument("--threads", type=int, nargs="+", default=[1, torch.get_num_threads()])
    a.add_argument("--hidden", type=int, default=NetworkConfig().rnn_hidden)
    a.add_argument("--out", default=str(ROOT / "bench" / "results" / "hsp_timing.json"))
    args = a.parse_args(argv)
    net = NetworkConfig(rnn_hidden=args.hidden)
    cfg = square_config(args.images, net)
    train_steps, inf_steps = (5, 100) if args.quick else (20, 1000)
    batch = TrainConfig().batch_size
    result = {
        "what": "HSP compute on CPU: one Adam step per network (batch 100, seq 10), pi+T per control step (1 thread)",
        "command": "python bench/hsp/timing.py " + " ".join(sys.argv[1:] if argv is None else argv),
        "network": {"rnn_hidden": net.rnn_hidden, "rnn_layers": net.rnn_layers, "gmm_modes": net.gmm_modes,
                    "mlp_hidden": list(net.mlp_hidden), "images": args.images, "batch": batch,
                    "seq_length": net.seq_length},
        "train_step": {str(t): train_step_ms(cfg, t, train_steps, batch) for t in args.threads},
        "inference": inference_ms(cfg, inf_steps),
        "goal_inference_ms": 5.0,
        "machine": machine_info(torch=torch.__version__, torch_threads_default=torch.get_num_threads()),
    }
    result["inference"]["meets_goal"] = result["inference"]["pi_plus_T_ms_median"] <= result["goal_inference_ms"]
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Loss curves of a training run as one PNG (matplotlib, headless)."""
from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

PANELS = (("policy", "π NLL"), ("policy_mse", "π action MSE (mode mean)"), ("termination", "T cross-entropy"),
          ("class", "HSP-Class cross-entropy"), ("initiation", "HSP-Reg NLL"), ("success_rate", "rollout success"))


def plot_losses(history: Sequence[Mapping[str, float]], path: str | Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [(k, t) for k, t in PANELS if any(k in h or f"valid_{k}" in h for h in history)]
    if not panels:
        return
    fig, axes = plt.subplots(1, len(panels), figsize=(4 * len(panels), 3.2), squeeze=False)
    for ax, (k, title) in zip(axes[0], panels):
        for key, label in ((k, "train"), (f"valid_{k}", "valid")):
            pts = [(h["epoch"], h[key]) for h in history if key in h]
            if pts:
                ax.plot(*zip(*pts), marker="." if len(pts) < 30 else None, label=label)
        ax.set_title(title)
        ax.set_xlabel("epoch")
        ax.legend()
        if k not in ("policy", "initiation", "success_rate") and all(h.get(k, 1) > 0 for h in history):
            ax.set_yscale("log")
    fig.tight_layout()
    tmp = Path(path).with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=80)
    plt.close(fig)
    tmp.replace(path)

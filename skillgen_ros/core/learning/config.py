"""Every HSP hyperparameter in one place, and the JSON config a checkpoint carries.

Defaults are robomimic's BC-RNN-GMM (robomimic/config/bc_config.py and the BC-RNN templates of
its study, which MimicGen and SkillMimicGen reuse): 2-layer LSTM of 400, sequence 10, GMM with
5 modes, min std 1e-4, softplus scale, Adam 1e-4, batch 100, 100 steps per epoch, 2000 epochs,
rollouts every 50 epochs. The termination / initiation networks follow the paper's appendix
"Training Procedures and Hyperparameters": MLP 2x1024 ("1014" in the text is a typo for 1024).
Smaller sizes (rnn_hidden, mlp_hidden) are options for CPU runs and are recorded in the config.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Mapping

from ..errors import ParameterError
from .normalization import MinMax, ObsStats

METHODS = ("skillgen", "mimicgen")


@dataclass(frozen=True)
class NetworkConfig:
    rnn_hidden: int = 400
    rnn_layers: int = 2
    seq_length: int = 10
    gmm_modes: int = 5
    gmm_min_std: float = 1e-4
    mlp_hidden: tuple[int, ...] = (1024, 1024)  # T (+Class head) and Reg trunks
    image_feature_dim: int = 64  # robomimic VisualCore feature_dimension
    spatial_keypoints: int = 32  # robomimic SpatialSoftmax num_kp
    pixel_shift: float = 0.1  # up to 10% of each image dimension (Appendix "Observation Spaces")

    def __post_init__(self):
        object.__setattr__(self, "mlp_hidden", tuple(int(h) for h in self.mlp_hidden))
        for name in ("rnn_hidden", "rnn_layers", "seq_length", "gmm_modes", "image_feature_dim", "spatial_keypoints"):
            if int(getattr(self, name)) < 1:
                raise ParameterError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not self.mlp_hidden or min(self.mlp_hidden) < 1:
            raise ParameterError(f"mlp_hidden must be positive sizes, got {self.mlp_hidden}")
        if not (self.gmm_min_std > 0 and 0 <= self.pixel_shift < 0.5):
            raise ParameterError("gmm_min_std must be > 0 and pixel_shift in [0, 0.5)")


REG_TARGETS = ("nominal", "initiation_target")  # what HSP-Reg's I learns (data.reg_target)
TERMINATION_LABEL_RULES = ("paper", "settled")  # what T learns as "terminate" (termination.termination_labels)


@dataclass(frozen=True)
class TrainConfig:
    lr: float = 1e-4
    batch_size: int = 100
    epochs: int = 2000
    steps_per_epoch: int = 100
    valid_ratio: float = 0.1  # robomimic split_train_val_from_hdf5 default
    seed: int = 0
    eval_every: int = 50  # epochs between evaluation rollouts (0: never); robomimic rollout.rate
    eval_rollouts: int = 50  # rollouts per evaluation (paper: 50 per checkpoint)
    initiation_window: int = 5  # first steps of each motion segment used as "end of the previous skill"
    device: str = "cpu"
    threads: int = 0  # torch CPU threads (0: torch's default); 1 is fastest on a shared, loaded machine
    reg_target: str = "nominal"  # HSP-Reg's target: the un-perturbed initiation or the stored label (data.reg_target)
    termination_labels: str = "paper"  # "settled" also labels a skill's still tail "terminate" (ours; docs/hsp.md)

    def __post_init__(self):
        if self.threads < 0:
            raise ParameterError(f"threads must be >= 0, got {self.threads}")
        if self.reg_target not in REG_TARGETS:
            raise ParameterError(f"reg_target must be one of {list(REG_TARGETS)}, got {self.reg_target!r}")
        if self.termination_labels not in TERMINATION_LABEL_RULES:
            raise ParameterError(f"termination_labels must be one of {list(TERMINATION_LABEL_RULES)}, "
                                 f"got {self.termination_labels!r}")
        if not (self.lr > 0 and self.batch_size >= 1 and self.epochs >= 1 and self.steps_per_epoch >= 1):
            raise ParameterError("lr must be > 0 and batch_size, epochs, steps_per_epoch >= 1")
        if (not 0 <= self.valid_ratio < 1 or self.eval_every < 0 or self.eval_rollouts < 1
                or self.initiation_window < 1 or self.seed < 0):
            raise ParameterError("valid_ratio in [0, 1), eval_every >= 0, eval_rollouts >= 1, initiation_window >= 1, "
                                 "seed >= 0")


@dataclass(frozen=True)
class HSPConfig:
    """What a checkpoint says about itself; stored as JSON beside the state_dicts."""

    task: str
    variant: str
    method: str  # dataset's generation method: "skillgen" (HSP) or "mimicgen" (BC-RNN baseline)
    skills: tuple[str, ...]
    low_dim_keys: tuple[str, ...]
    image_keys: tuple[str, ...]
    obs_shapes: Mapping[str, tuple[int, ...]]  # per-step shape of every key the networks read
    object_ids: tuple[str, ...]
    num_source_demos: int
    all_steps: bool  # π trained on every step (MimicGen baseline) instead of skill steps only
    has_termination: bool
    has_class: bool
    has_reg: bool
    obs_stats: ObsStats
    initiation_norm: MinMax | None
    dataset_sha256: str
    dataset_path: str
    train_demos: tuple[str, ...]
    valid_demos: tuple[str, ...]
    network: NetworkConfig = NetworkConfig()
    train: TrainConfig = TrainConfig()
    step: int = 0
    epoch: int = 0
    best: Mapping[str, Any] = field(default_factory=dict)  # {"metric", "value", "epoch", "step"}
    history: tuple[Mapping[str, float], ...] = ()  # one record per epoch

    @property
    def obs_keys(self) -> tuple[str, ...]:
        return self.low_dim_keys + self.image_keys

    def to_json(self) -> dict:
        d = dataclasses.asdict(self)
        d["obs_stats"] = self.obs_stats.to_json()
        d["initiation_norm"] = self.initiation_norm.to_json() if self.initiation_norm else None
        d["obs_shapes"] = {k: list(v) for k, v in self.obs_shapes.items()}
        d["history"] = [dict(h) for h in self.history]
        d["best"] = dict(self.best)
        return d

    @staticmethod
    def from_json(d: Mapping) -> "HSPConfig":
        """Raises KeyError/TypeError/ValueError for a malformed config (the loader wraps them)."""
        d = dict(d)
        known = {f.name for f in dataclasses.fields(HSPConfig)}
        unknown = set(d) - known
        if unknown:
            raise ValueError(f"unknown config fields {sorted(unknown)}")
        d["network"] = NetworkConfig(**d["network"])
        # checkpoints from before reg_target existed trained I on the stored labels
        d["train"] = TrainConfig(**{"reg_target": "initiation_target", **d["train"]})
        d["obs_stats"] = ObsStats.from_json(d["obs_stats"])
        d["initiation_norm"] = MinMax.from_json(d["initiation_norm"]) if d.get("initiation_norm") else None
        d["obs_shapes"] = {k: tuple(int(x) for x in v) for k, v in d["obs_shapes"].items()}
        for k in ("skills", "low_dim_keys", "image_keys", "object_ids", "train_demos", "valid_demos"):
            d[k] = tuple(d[k])
        d["history"] = tuple(d.get("history", ()))
        cfg = HSPConfig(**d)
        if cfg.method not in METHODS:
            raise ValueError(f"unknown method {cfg.method!r}")
        return cfg

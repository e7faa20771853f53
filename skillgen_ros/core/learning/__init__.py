"""Hybrid Skill Policies: learning π, T and I from generated datasets (paper Sec. "Policy Learning").

Runtime API (what deployment imports): `policy_obs`, `load_hsp`, `HybridSkillPolicy`,
`CheckpointError`. Training: `trainer.train(TrainRequest)` / `skillgen train`. See docs/hsp.md.
"""
from ..errors import CheckpointError
from .checkpoint import load_hsp
from .hsp import HybridSkillPolicy
from .observation import policy_obs

__all__ = ["CheckpointError", "HybridSkillPolicy", "load_hsp", "policy_obs"]

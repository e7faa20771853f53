"""Deployment of Hybrid Skill Policies (paper Sec. 4, Algorithm 2): the pure executor and evaluation.

`run_rollout` (rollout.py) runs one rollout over any GenerationEnv; `evaluate` runs N of them
in-process on held-out reset seeds (seeds.py) and summarizes them (evaluate.py). The hsp node
(nodes/hsp.py) runs the same executor over the ROS graph.
"""
from .evaluate import EvalSummary, evaluate, summarize
from .initiation import MODES
from .outcome import DeployReason
from .rollout import DeployConfig, RolloutResult, SkillLog, run_rollout
from .seeds import rollout_seed

__all__ = ["MODES", "DeployConfig", "DeployReason", "EvalSummary", "RolloutResult", "SkillLog", "evaluate",
           "rollout_seed", "run_rollout", "summarize"]

"""HybridSkillPolicy: the learned parameterized skill <I, π, T> that deployment calls.

One object per checkpoint, shared by every skill of the task (the paper trains one network of
each type across all skills). A rollout calls, per skill: `initiation_source_demo(o)` (HSP-Class)
or `initiation_pose(o)` (HSP-Reg) on the last observation of the previous skill, then
`start_skill(i)`, then `act(o)` / `terminated(o)` every 20 Hz step. Everything is deterministic
(the mean of the most probable GMM mode; argmax of the classifiers), so two processes given the
same observations return the same actions.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np
import torch

from ..errors import CheckpointError, InvalidInputError
from .config import HSPConfig
from .observation import check_obs
from .rotation import pos_rot6d_to_pose
from .termination import CONSECUTIVE, TERMINATE, TerminationFilter


class HybridSkillPolicy:
    """π, T and I of one checkpoint, on one device, in eval mode."""

    def __init__(self, config: HSPConfig, networks: Mapping[str, torch.nn.Module], device: str = "cpu"):
        self.config = config
        self.device = torch.device(device)
        self.nets = {k: n.to(self.device).eval() for k, n in networks.items()}
        self._read_shapes = {k: config.obs_shapes[k] for k in config.obs_keys}
        self.filter = TerminationFilter(CONSECUTIVE)
        self.skill_index = -1
        self._state = None
        self._counter = 0

    # -- observation -> tensors ------------------------------------------------------------
    def _tensors(self, obs: Mapping[str, np.ndarray]) -> dict[str, torch.Tensor]:
        check_obs(obs, self._read_shapes)
        st = self.config.obs_stats
        out = {}
        for k in self.config.low_dim_keys:
            x = st.normalize(k, np.asarray(obs[k], float).reshape(-1))
            out[k] = torch.as_tensor(x, dtype=torch.float32, device=self.device)[None]
        for k in self.config.image_keys:
            out[k] = torch.as_tensor(np.asarray(obs[k], np.uint8), device=self.device)[None]
        return out

    def _net(self, name: str, what: str):
        if name not in self.nets:
            raise CheckpointError(f"checkpoint has no {what} (method {self.config.method}, "
                                  f"heads: termination={self.config.has_termination}, class={self.config.has_class}, "
                                  f"reg={self.config.has_reg})")
        return self.nets[name]

    # -- π --------------------------------------------------------------------------------
    def start_skill(self, skill_index: int) -> None:
        """A new skill segment begins: fresh LSTM state and termination counter."""
        if not 0 <= int(skill_index) < max(1, len(self.config.skills)):
            raise InvalidInputError(f"skill index {skill_index} out of range for {list(self.config.skills)}")
        self.skill_index = int(skill_index)
        self._state = None
        self._counter = 0
        self.filter.reset()

    @torch.inference_mode()
    def act(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        """(7,) normalized action (docs/dataset.md "Actions"). The LSTM state restarts every
        seq_length steps, as robomimic's BC_RNN.get_action does, matching the training windows."""
        t = self._tensors(obs)
        if self._counter % self.config.network.seq_length == 0:
            self._state = None
        self._counter += 1
        a, self._state = self.nets["policy"].step(t, self._state)
        return a[0].double().cpu().numpy()

    # -- T --------------------------------------------------------------------------------
    @torch.inference_mode()
    def termination_probability(self, obs: Mapping[str, np.ndarray]) -> float:
        logits, _ = self._net("termination", "termination classifier")(self._tensors(obs))
        return float(torch.softmax(logits, -1)[0, TERMINATE])

    def terminated(self, obs: Mapping[str, np.ndarray]) -> bool:
        """True once T predicted "terminate" on 5 consecutive calls since start_skill."""
        return self.filter.update(self.termination_probability(obs) > 0.5)

    # -- I --------------------------------------------------------------------------------
    @torch.inference_mode()
    def initiation_source_demo(self, obs: Mapping[str, np.ndarray]) -> int:
        """HSP-Class: index of the source demo whose initiation to adapt for the next skill."""
        net = self._net("termination", "HSP-Class head")
        if net.cls is None:
            raise CheckpointError("checkpoint has no HSP-Class head")
        _, cls = net(self._tensors(obs))
        return int(cls[0].argmax())

    @torch.inference_mode()
    def initiation_pose(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        """HSP-Reg: (7,) world pose x y z qx qy qz qw for the next skill's initiation."""
        y = self._net("initiation", "HSP-Reg initiation network").predict(self._tensors(obs))[0].double().cpu().numpy()
        return pos_rot6d_to_pose(self.config.initiation_norm.unnormalize(y))

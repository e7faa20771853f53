"""HSP's three networks: π (BC-RNN-GMM), T (termination classifier + HSP-Class head), I (HSP-Reg GMM).

Each has its own ObservationEncoder (low-dim keys concatenated with one ResNet-18 + spatial
softmax feature per camera), as the paper's appendix says ("same observation encoder structure,
with different learned weights"). The GMM head follows robomimic's RNNGMMActorNetwork: linear
decoders for means, scales and logits; means squashed with tanh (use_tanh=False), scales
softplus + min_std; the loss is the mixture's negative log-likelihood.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import torch
from torch import distributions as D
from torch import nn
from torch.nn import functional as F

from .config import NetworkConfig
from .resnet import ImageEncoder

ACTION_DIM = 7  # dpos (3), drot (3), gripper (docs/dataset.md "Actions")
INITIATION_DIM = 9  # position (3) + 6D rotation (Zhou et al.)


class ObservationEncoder(nn.Module):
    """dict of (N, ...) tensors -> (N, out_dim): low-dim (normalized float) then image features."""

    def __init__(self, low_dim: Mapping[str, int], image_keys: Sequence[str], net: NetworkConfig):
        super().__init__()
        self.low_dim_keys = tuple(low_dim)
        self.image_keys = tuple(image_keys)
        self.images = nn.ModuleDict({k: ImageEncoder(net.image_feature_dim, net.spatial_keypoints, net.pixel_shift)
                                     for k in self.image_keys})
        self.out_dim = sum(low_dim.values()) + net.image_feature_dim * len(self.image_keys)

    def forward(self, obs: Mapping[str, torch.Tensor]) -> torch.Tensor:
        parts = [obs[k] for k in self.low_dim_keys] + [self.images[k](obs[k]) for k in self.image_keys]
        return torch.cat(parts, dim=-1)


def _flat(obs: Mapping[str, torch.Tensor], lead: int) -> dict[str, torch.Tensor]:
    """Merge the first `lead` dims into one batch dim."""
    return {k: v.reshape(-1, *v.shape[lead:]) for k, v in obs.items()}


class GMMHead(nn.Module):
    """features (..., F) -> mixture of `modes` diagonal Gaussians over (..., out_dim)."""

    def __init__(self, in_dim: int, out_dim: int, modes: int, min_std: float):
        super().__init__()
        self.out_dim, self.modes, self.min_std = out_dim, modes, min_std
        self.mean = nn.Linear(in_dim, modes * out_dim)
        self.scale = nn.Linear(in_dim, modes * out_dim)
        self.logits = nn.Linear(in_dim, modes)

    def params(self, h: torch.Tensor):
        shape = (*h.shape[:-1], self.modes, self.out_dim)
        means = torch.tanh(self.mean(h).reshape(shape))
        scales = F.softplus(self.scale(h).reshape(shape)) + self.min_std
        return means, scales, self.logits(h)

    def nll(self, h: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        means, scales, logits = self.params(h)
        comp = D.Independent(D.Normal(means, scales), 1)
        dist = D.MixtureSameFamily(D.Categorical(logits=logits), comp)
        return -dist.log_prob(target).mean()

    def mode_mean(self, h: torch.Tensor) -> torch.Tensor:
        """Mean of the most probable mode: a deterministic prediction (same rollout in any process)."""
        means, _, logits = self.params(h)
        idx = logits.argmax(-1)[..., None, None].expand(*means.shape[:-2], 1, self.out_dim)
        return means.gather(-2, idx).squeeze(-2)


class BCRNNGMM(nn.Module):
    """π: encoder -> LSTM -> GMM over the 7-D normalized action (robomimic BC-RNN-GMM)."""

    def __init__(self, encoder: ObservationEncoder, net: NetworkConfig):
        super().__init__()
        self.encoder = encoder
        self.rnn = nn.LSTM(encoder.out_dim, net.rnn_hidden, net.rnn_layers, batch_first=True)
        self.head = GMMHead(net.rnn_hidden, ACTION_DIM, net.gmm_modes, net.gmm_min_std)

    def features(self, obs: Mapping[str, torch.Tensor]) -> torch.Tensor:
        """obs (B, T, ...) -> LSTM outputs (B, T, H) from a zero state (one training window)."""
        b, t = next(iter(obs.values())).shape[:2]
        z = self.encoder(_flat(obs, 2)).reshape(b, t, -1)
        return self.rnn(z)[0]

    def loss(self, obs: Mapping[str, torch.Tensor], actions: torch.Tensor) -> torch.Tensor:
        return self.head.nll(self.features(obs), actions)

    def step(self, obs: Mapping[str, torch.Tensor], state=None):
        """One control step: obs (B, ...) -> (action (B, 7), new LSTM state)."""
        z = self.encoder(obs)[:, None]
        out, state = self.rnn(z, state)
        return self.head.mode_mean(out[:, 0]), state


def _mlp(in_dim: int, hidden: Sequence[int]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for h in hidden:
        layers += [nn.Linear(in_dim, h), nn.ReLU()]
        in_dim = h
    return nn.Sequential(*layers)


class TerminationNet(nn.Module):
    """T: encoder -> MLP -> 2 logits (running, terminate); HSP-Class: an extra head on the same trunk."""

    def __init__(self, encoder: ObservationEncoder, net: NetworkConfig, num_classes: int = 0):
        super().__init__()
        self.encoder = encoder
        self.trunk = _mlp(encoder.out_dim, net.mlp_hidden)
        self.term = nn.Linear(net.mlp_hidden[-1], 2)
        self.cls = nn.Linear(net.mlp_hidden[-1], num_classes) if num_classes > 0 else None

    def forward(self, obs: Mapping[str, torch.Tensor]):
        """obs (N, ...) -> (termination logits (N, 2), class logits (N, C) or None)."""
        h = self.trunk(self.encoder(obs))
        return self.term(h), (self.cls(h) if self.cls is not None else None)


class InitiationRegNet(nn.Module):
    """HSP-Reg I: encoder -> MLP -> GMM over the [-1, 1]-normalized (position, 6D rotation) target."""

    def __init__(self, encoder: ObservationEncoder, net: NetworkConfig):
        super().__init__()
        self.encoder = encoder
        self.trunk = _mlp(encoder.out_dim, net.mlp_hidden)
        self.head = GMMHead(net.mlp_hidden[-1], INITIATION_DIM, net.gmm_modes, net.gmm_min_std)

    def loss(self, obs: Mapping[str, torch.Tensor], target: torch.Tensor) -> torch.Tensor:
        return self.head.nll(self.trunk(self.encoder(obs)), target)

    def predict(self, obs: Mapping[str, torch.Tensor]) -> torch.Tensor:
        return self.head.mode_mean(self.trunk(self.encoder(obs)))


def build_networks(cfg) -> dict[str, nn.Module]:
    """The networks an HSPConfig describes: "policy" always, "termination" and "initiation" if trained."""
    low_dim = {k: int(torch.Size(cfg.obs_shapes[k]).numel()) for k in cfg.low_dim_keys}

    def enc():
        return ObservationEncoder(low_dim, cfg.image_keys, cfg.network)

    nets: dict[str, nn.Module] = {"policy": BCRNNGMM(enc(), cfg.network)}
    if cfg.has_termination:
        nets["termination"] = TerminationNet(enc(), cfg.network, cfg.num_source_demos if cfg.has_class else 0)
    if cfg.has_reg:
        nets["initiation"] = InitiationRegNet(enc(), cfg.network)
    return nets

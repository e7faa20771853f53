"""The image encoder of the paper and robomimic: ResNet-18 conv trunk + spatial softmax, in plain torch.

robomimic's VisualCore (ResNet18Conv, untrained, then SpatialSoftmax with 32 keypoints and a
linear layer to 64 features). torchvision's wheel does not load against the CPU torch these
machines install, so the trunk is written here (He et al. 2016: BasicBlock, [2, 2, 2, 2]).
Pixel shift (DrQ / Kostrikov et al., the paper's "shift image pixels by up to 10%") pads with
edge pixels and crops back at a random integer offset, in training mode only.
"""
from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F


class BasicBlock(nn.Module):
    def __init__(self, cin: int, cout: int, stride: int):
        super().__init__()
        self.conv1 = nn.Conv2d(cin, cout, 3, stride, 1, bias=False)
        self.bn1 = nn.BatchNorm2d(cout)
        self.conv2 = nn.Conv2d(cout, cout, 3, 1, 1, bias=False)
        self.bn2 = nn.BatchNorm2d(cout)
        self.down = None
        if stride != 1 or cin != cout:
            self.down = nn.Sequential(nn.Conv2d(cin, cout, 1, stride, bias=False), nn.BatchNorm2d(cout))

    def forward(self, x):
        y = F.relu(self.bn1(self.conv1(x)))
        y = self.bn2(self.conv2(y))
        return F.relu(y + (x if self.down is None else self.down(x)))


class ResNet18Conv(nn.Module):
    """ResNet-18 without its pooling and classifier: (N, 3, H, W) -> (N, 512, H/32, W/32)."""

    def __init__(self):
        super().__init__()
        self.stem = nn.Sequential(nn.Conv2d(3, 64, 7, 2, 3, bias=False), nn.BatchNorm2d(64), nn.ReLU(),
                                  nn.MaxPool2d(3, 2, 1))
        layers, cin = [], 64
        for cout, stride in ((64, 1), (128, 2), (256, 2), (512, 2)):
            layers += [BasicBlock(cin, cout, stride), BasicBlock(cout, cout, 1)]
            cin = cout
        self.layers = nn.Sequential(*layers)

    def forward(self, x):
        return self.layers(self.stem(x))


class SpatialSoftmax(nn.Module):
    """Finn et al. 2016: 1x1 conv to K maps, softmax over pixels, expected (x, y) in [-1, 1] -> (N, 2K)."""

    def __init__(self, channels: int, keypoints: int):
        super().__init__()
        self.proj = nn.Conv2d(channels, keypoints, 1)

    def forward(self, x):
        x = self.proj(x)
        n, k, h, w = x.shape
        attn = F.softmax(x.reshape(n, k, h * w), dim=-1)
        ys, xs = torch.meshgrid(torch.linspace(-1, 1, h, device=x.device), torch.linspace(-1, 1, w, device=x.device),
                                indexing="ij")
        ex = (attn * xs.reshape(1, 1, -1)).sum(-1)
        ey = (attn * ys.reshape(1, 1, -1)).sum(-1)
        return torch.stack([ex, ey], dim=-1).reshape(n, 2 * k)


def pixel_shift(x: torch.Tensor, frac: float) -> torch.Tensor:
    """Random integer shift of each image by up to frac of its size (edge padding), (N, C, H, W)."""
    n, _, h, w = x.shape
    ph, pw = int(round(frac * h)), int(round(frac * w))
    if ph == 0 and pw == 0:
        return x
    padded = F.pad(x, (pw, pw, ph, ph), mode="replicate")
    dy = torch.randint(0, 2 * ph + 1, (n,), device=x.device)
    dx = torch.randint(0, 2 * pw + 1, (n,), device=x.device)
    rows = (dy[:, None] + torch.arange(h, device=x.device)[None])  # (N, H)
    cols = (dx[:, None] + torch.arange(w, device=x.device)[None])  # (N, W)
    idx = torch.arange(n, device=x.device)[:, None, None]
    out = padded.permute(0, 2, 3, 1)[idx, rows[:, :, None], cols[:, None, :]]  # (N, H, W, C)
    return out.permute(0, 3, 1, 2)


class ImageEncoder(nn.Module):
    """uint8 (N, H, W, 3) -> (N, feature_dim)."""

    def __init__(self, feature_dim: int = 64, keypoints: int = 32, shift: float = 0.1):
        super().__init__()
        self.trunk = ResNet18Conv()
        self.pool = SpatialSoftmax(512, keypoints)
        self.fc = nn.Linear(2 * keypoints, feature_dim)
        self.shift = shift

    def forward(self, img: torch.Tensor) -> torch.Tensor:
        x = img.permute(0, 3, 1, 2).float() / 255.0
        if self.training and self.shift > 0:
            x = pixel_shift(x, self.shift)
        return self.fc(self.pool(self.trunk(x)))

"""Parts shared by the built-in detectors: the FPN-lite neck and the CenterNet head."""
from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F

from workbench.detect.centernet import init_heatmap_bias


def conv_bn_relu(c_in: int, c_out: int, kernel: int = 3, stride: int = 1, groups: int = 1,
                 relu: type[nn.Module] | None = nn.ReLU) -> nn.Sequential:
    layers = [nn.Conv2d(c_in, c_out, kernel, stride, kernel // 2, groups=groups, bias=False),
              nn.BatchNorm2d(c_out)]
    if relu is not None:
        layers.append(relu(inplace=True))
    return nn.Sequential(*layers)


class FPNLite(nn.Module):
    """Top-down feature pyramid with 1×1 laterals and one depthwise-separable 3×3 merge at the finest level.

    Takes features at strides 4, 8, 16, 32 (fine to coarse) and returns one map of `channels` at
    the finest one. Coarser maps are upsampled (nearest) to the exact size of the finer map, so any
    input size works (e.g. 240 rows → 60, 30, 15, 8)."""

    def __init__(self, in_channels: list[int], channels: int):
        super().__init__()
        self.laterals = nn.ModuleList(conv_bn_relu(c, channels, kernel=1, relu=None) for c in in_channels)
        self.merge = nn.Sequential(conv_bn_relu(channels, channels, groups=channels),
                                   conv_bn_relu(channels, channels, kernel=1))

    def forward(self, features: list[torch.Tensor]) -> torch.Tensor:
        top = self.laterals[-1](features[-1])
        for lateral, feature in zip(self.laterals[-2::-1], features[-2::-1]):
            top = lateral(feature) + F.interpolate(top, size=feature.shape[-2:], mode="nearest")
        return self.merge(top)


class CenterNetHead(nn.Module):
    """Three branches: class heat-map logits, box size, centre offset. Each is a depthwise-separable
    3×3 convolution (3×3 per channel, then 1×1 to head_channels) + ReLU + 1×1 output convolution:
    the same receptive field as CenterNet's full 3×3 convolution at a tenth of its cost, which
    on the CPU was more than the whole 'mobile' backbone (bench detect)."""

    def __init__(self, channels: int, num_classes: int, head_channels: int):
        super().__init__()

        def branch(c_out: int) -> nn.Sequential:
            return nn.Sequential(nn.Conv2d(channels, channels, 3, padding=1, groups=channels),
                                 nn.Conv2d(channels, head_channels, 1), nn.ReLU(inplace=True),
                                 nn.Conv2d(head_channels, c_out, 1))
        self.heatmap, self.size, self.offset = branch(num_classes), branch(2), branch(2)
        init_heatmap_bias(self.heatmap[-1])

    def forward(self, x: torch.Tensor) -> dict[str, torch.Tensor]:
        return {"heatmap": self.heatmap(x), "size": self.size(x), "offset": self.offset(x)}


class PyramidDetector(nn.Module):
    """backbone (→ features at strides 4…32 of the image) → FPN-lite → CenterNet head (stride 4)."""

    def __init__(self, backbone: nn.Module, feature_channels: list[int], num_classes: int,
                 neck_channels: int, head_channels: int):
        super().__init__()
        self.backbone = backbone
        self.neck = FPNLite(feature_channels, neck_channels)
        self.head = CenterNetHead(neck_channels, num_classes, head_channels)

    def forward(self, x: torch.Tensor) -> dict[str, torch.Tensor]:
        return self.head(self.neck(self.backbone(x)))

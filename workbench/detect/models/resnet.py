"""'resnet18': ResNet-18 layout + FPN-lite + CenterNet head (the paper's R-FCN-ResNet101 role)."""
from __future__ import annotations

import torch
from torch import nn

from workbench.detect.models.neck_head import PyramidDetector, conv_bn_relu
from workbench.detect.models.registry import register_detector

STAGE_CHANNELS = (64, 128, 256, 512)
BLOCKS_PER_STAGE = (2, 2, 2, 2)
NECK_CHANNELS = 64
HEAD_CHANNELS = 64


class BasicBlock(nn.Module):
    def __init__(self, c_in: int, c_out: int, stride: int):
        super().__init__()
        self.body = nn.Sequential(conv_bn_relu(c_in, c_out, stride=stride),
                                  conv_bn_relu(c_out, c_out, relu=None))
        self.shortcut = (nn.Identity() if stride == 1 and c_in == c_out
                         else conv_bn_relu(c_in, c_out, kernel=1, stride=stride, relu=None))
        self.relu = nn.ReLU(inplace=True)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.relu(self.body(x) + self.shortcut(x))


class ResNet18Features(nn.Module):
    """ResNet-18 (7×7 stem, max-pool, four stages of two basic blocks); returns the stage outputs at
    image strides 4, 8, 16, 32. input_stride 2 (packed raw) makes the stem conv stride 1."""

    def __init__(self, in_channels: int, input_stride: int):
        super().__init__()
        self.stem = nn.Sequential(conv_bn_relu(in_channels, STAGE_CHANNELS[0], kernel=7, stride=2 // input_stride),
                                  nn.MaxPool2d(3, stride=2, padding=1))
        stages, c = [], STAGE_CHANNELS[0]
        for i, (c_out, n) in enumerate(zip(STAGE_CHANNELS, BLOCKS_PER_STAGE)):
            stages.append(nn.Sequential(*(BasicBlock(c if j == 0 else c_out, c_out, 2 if (i > 0 and j == 0) else 1)
                                          for j in range(n))))
            c = c_out
        self.stages = nn.ModuleList(stages)
        self.channels = list(STAGE_CHANNELS)

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        x = self.stem(x)
        features = []
        for stage in self.stages:
            x = stage(x)
            features.append(x)
        return features


@register_detector("resnet18")
def resnet18(in_channels: int, num_classes: int, input_stride: int = 1) -> nn.Module:
    """ResNet-18 features (strides 4–32) → FPN-lite (64 ch) → CenterNet head (64 ch)."""
    backbone = ResNet18Features(in_channels, input_stride)
    return PyramidDetector(backbone, backbone.channels, num_classes, NECK_CHANNELS, HEAD_CHANNELS)

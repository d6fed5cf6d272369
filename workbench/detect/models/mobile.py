"""'mobile': MobileNetV2 layout at width 0.5 + FPN-lite + CenterNet head (the paper's SSD-MobileNet role)."""
from __future__ import annotations

import torch
from torch import nn

from workbench.detect.models.neck_head import PyramidDetector, conv_bn_relu
from workbench.detect.models.registry import register_detector

# MobileNetV2 (Sandler et al. 2018), table 2: expansion t, channels c, repeats n, first stride s.
MOBILENET_V2_LAYOUT = ((1, 16, 1, 1), (6, 24, 2, 2), (6, 32, 3, 2), (6, 64, 4, 2),
                       (6, 96, 3, 1), (6, 160, 3, 2), (6, 320, 1, 1))
# Stages whose output feeds the neck: strides 4, 8, 16, 32 of the image.
FEATURE_STAGES = (1, 2, 4, 6)
WIDTH = 0.5
NECK_CHANNELS = 48
HEAD_CHANNELS = 32


def _divisible(channels: float, divisor: int = 8) -> int:
    """MobileNet's channel rounding: nearest multiple of divisor, never below 90 % of the request."""
    rounded = max(divisor, int(channels + divisor / 2) // divisor * divisor)
    return rounded + divisor if rounded < 0.9 * channels else rounded


class InvertedResidual(nn.Module):
    def __init__(self, c_in: int, c_out: int, stride: int, expansion: int):
        super().__init__()
        hidden = c_in * expansion
        layers = [] if expansion == 1 else [conv_bn_relu(c_in, hidden, kernel=1, relu=nn.ReLU6)]
        layers += [conv_bn_relu(hidden, hidden, stride=stride, groups=hidden, relu=nn.ReLU6),
                   conv_bn_relu(hidden, c_out, kernel=1, relu=None)]
        self.block = nn.Sequential(*layers)
        self.residual = stride == 1 and c_in == c_out

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.block(x) if self.residual else self.block(x)


class MobileNetV2Features(nn.Module):
    """MobileNetV2 without its last 1×1 conv and classifier; returns the four FEATURE_STAGES maps.

    input_stride 2 (packed raw) makes the stem stride 1, so features keep their image strides."""

    def __init__(self, in_channels: int, input_stride: int, width: float = WIDTH):
        super().__init__()
        c = _divisible(32 * width)
        self.stem = conv_bn_relu(in_channels, c, stride=2 // input_stride, relu=nn.ReLU6)
        self.stages = nn.ModuleList()
        self.channels: list[int] = []
        for t, c_out, n, s in MOBILENET_V2_LAYOUT:
            c_out = _divisible(c_out * width)
            self.stages.append(nn.Sequential(*(InvertedResidual(c if i == 0 else c_out, c_out, s if i == 0 else 1, t)
                                               for i in range(n))))
            self.channels.append(c_out)
            c = c_out
        self.channels = [self.channels[i] for i in FEATURE_STAGES]

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        x = self.stem(x)
        features = []
        for i, stage in enumerate(self.stages):
            x = stage(x)
            if i in FEATURE_STAGES:
                features.append(x)
        return features


@register_detector("mobile")
def mobile(in_channels: int, num_classes: int, input_stride: int = 1) -> nn.Module:
    """MobileNetV2 ×0.5 features (strides 4–32) → FPN-lite (48 ch) → CenterNet head (32 ch)."""
    backbone = MobileNetV2Features(in_channels, input_stride)
    return PyramidDetector(backbone, backbone.channels, num_classes, NECK_CHANNELS, HEAD_CHANNELS)

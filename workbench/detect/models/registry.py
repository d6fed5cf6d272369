"""The DETECTORS registry: name → factory(in_channels, num_classes, input_stride) → torch.nn.Module."""
from __future__ import annotations

from typing import Callable

from workbench.errors import ParameterError
from workbench.registry import Registry

DETECTORS: Registry[Callable] = Registry("detector", "detector")

INPUT_STRIDES = (1, 2)


def register_detector(name: str):
    """Decorator: register `factory(in_channels, num_classes, input_stride) -> nn.Module` as `name`.

    This is the entry point for a user's own network. The module's forward(x) takes a B×C×H×W
    float32 batch and returns {"heatmap": B×K×h×w logits, "size": B×2×h×w, "offset": B×2×h×w}
    at output stride 4 in ORIGINAL image pixels: h = ceil(H_image / 4). input_stride is the
    input's own stride relative to the image (1 for linear / sRGB, 2 for packed raw, whose
    4×H/2×W/2 planes the network must not downsample as much). See centernet.py for what the
    three maps mean; centernet.init_heatmap_bias sets the prior the loss expects.

        @register_detector("tiny")
        def tiny(in_channels, num_classes, input_stride):
            return MyNet(in_channels, num_classes, input_stride)
    """
    return DETECTORS.register(name)


def build_detector(name: str, in_channels: int, num_classes: int, input_stride: int = 1):
    """A fresh (randomly initialised) detector from the registry."""
    factory = DETECTORS[name]          # ParameterError listing the registered names
    if not (isinstance(in_channels, int) and in_channels >= 1):
        raise ParameterError("in_channels", in_channels, "a positive integer")
    if not (isinstance(num_classes, int) and num_classes >= 1):
        raise ParameterError("num_classes", num_classes, "a positive integer")
    if input_stride not in INPUT_STRIDES:
        raise ParameterError("input_stride", input_stride, f"one of {INPUT_STRIDES}")
    import torch
    net = factory(in_channels, num_classes, input_stride)
    if not isinstance(net, torch.nn.Module):
        raise ParameterError("detector", name, f"a factory that returns a torch.nn.Module (it returned a "
                                               f"{type(net).__name__})")
    if not any(p.requires_grad for p in net.parameters()):
        raise ParameterError("detector", name, "a network with trainable parameters (this one has none)")
    return net

"""Detector networks: the DETECTORS registry and the built-in backbones ('mobile', 'resnet18').

    net = build_detector("mobile", in_channels=3, num_classes=3)            # sRGB / linear
    net = build_detector("resnet18", in_channels=4, num_classes=3, input_stride=2)   # packed raw
"""
from workbench.detect.models.registry import DETECTORS, build_detector, register_detector
from workbench.detect.models import mobile as _mobile, resnet as _resnet  # noqa: F401  (register)

__all__ = ["DETECTORS", "build_detector", "register_detector"]

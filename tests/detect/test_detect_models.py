"""Built-in detectors: output shapes at stride 4 for every input stride, sizes, prior, user nets."""
import math

import pytest
import torch
from torch import nn

from workbench.detect.centernet import HEATMAP_PRIOR, centernet_loss, collate_targets, encode_targets
from workbench.detect.models import DETECTORS, build_detector, register_detector
from workbench.errors import ParameterError

torch.set_num_threads(1)


@pytest.mark.parametrize("name, params_m", [("mobile", (0.4, 0.7)), ("resnet18", (10.5, 12.0))])
@pytest.mark.parametrize("channels, stride", [(3, 1), (4, 2)])
def test_outputs_at_stride_four_of_the_image(name, params_m, channels, stride):
    net = build_detector(name, channels, 3, stride).eval()
    count = sum(p.numel() for p in net.parameters()) / 1e6
    assert params_m[0] < count < params_m[1]
    image_hw = (60, 84)                    # not a multiple of 32: the neck must still line up
    with torch.no_grad():
        out = net(torch.rand(2, channels, image_hw[0] // stride, image_hw[1] // stride))
    assert out["heatmap"].shape == (2, 3, 15, 21)
    assert out["size"].shape == out["offset"].shape == (2, 2, 15, 21)
    prior = torch.sigmoid(net.head.heatmap[-1].bias)
    assert torch.allclose(prior, torch.full_like(prior, HEATMAP_PRIOR))


def test_unknown_detector_and_bad_stride():
    with pytest.raises(ParameterError, match="detector"):
        build_detector("yolo", 3, 3)
    with pytest.raises(ParameterError, match="input_stride"):
        build_detector("mobile", 3, 3, input_stride=4)


def test_user_module_plugs_in_through_the_registry(monkeypatch):
    monkeypatch.setattr(DETECTORS, "_methods", dict(DETECTORS._methods))   # registration undone after the test
    class Tiny(nn.Module):
        def __init__(self, c, k, s):
            super().__init__()
            self.body = nn.Conv2d(c, 8, 3, stride=4 // s, padding=1)
            self.heat, self.size, self.offset = nn.Conv2d(8, k, 1), nn.Conv2d(8, 2, 1), nn.Conv2d(8, 2, 1)

        def forward(self, x):
            f = torch.relu(self.body(x))
            return {"heatmap": self.heat(f), "size": self.size(f), "offset": self.offset(f)}

    register_detector("tiny_test")(Tiny)
    assert "tiny_test" in DETECTORS.names
    net = build_detector("tiny_test", 4, 2, input_stride=2)
    targets = collate_targets([encode_targets([[4, 4, 20, 12]], [1], 2, (32, 48))])
    total, _ = centernet_loss(net(torch.rand(1, 4, 16, 24)), targets)
    total.backward()
    assert math.isfinite(total.item()) and net.body.weight.grad is not None


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
@pytest.mark.parametrize("name", ["mobile", "resnet18"])
def test_train_step_and_decode_on_cuda(name):
    from workbench.detect.centernet import decode
    net = build_detector(name, 4, 3, input_stride=2).cuda()
    targets = collate_targets([encode_targets([[8, 8, 40, 30]], [2], 3, (64, 96))] * 2)
    outputs = net(torch.rand(2, 4, 32, 48, device="cuda"))
    total, parts = centernet_loss(outputs, {k: v.cuda() for k, v in targets.items()})
    total.backward()
    assert parts["heatmap"].device.type == "cuda" and math.isfinite(total.item())
    assert len(decode(outputs)) == 2


@pytest.mark.parametrize("name", [123, "", "x" * 41, "has space", None])
def test_a_detector_name_that_no_project_file_can_spell_is_refused(name):
    with pytest.raises(ParameterError, match="detector name"):
        register_detector(name)


def test_a_factory_that_returns_no_trainable_network_is_named(monkeypatch):
    monkeypatch.setattr(DETECTORS, "_methods", dict(DETECTORS._methods))
    register_detector("returns-none")(lambda c, k, s: None)
    register_detector("no-params")(lambda c, k, s: torch.nn.Identity())
    with pytest.raises(ParameterError, match="torch.nn.Module.*NoneType"):
        build_detector("returns-none", 3, 2)
    with pytest.raises(ParameterError, match="trainable parameters"):
        build_detector("no-params", 3, 2)

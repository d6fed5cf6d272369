"""A built-in net overfits tiny images (coloured boxes on noise) to AP@0.5 > 0.95: the head, loss,
decoder and evaluator work together, on RGB input (stride 1) and on the packed RGGB mosaic of the
same images (stride 2, boxes still decoded at stride 4 of the image), and under bf16 autocast (the
CUDA mixed-precision path, run on the CPU). One torch thread, ~12 s each in float32 on 8 images;
bf16 on a CPU without native bf16 is emulated (~0.25 s a step on 4 images on an AVX2 EPYC), so that
case fits 4 images in 70 steps (AP 1.0; 50 steps do not fit them)."""
import numpy as np
import pytest
import torch

from workbench.detect.centernet import centernet_loss, collate_targets, decode, encode_targets
from workbench.detect.evaluate import evaluate_map
from workbench.detect.models import build_detector
from workbench.detect.representations import pack_raw
from workbench.detect.devices import autocast, autocast_dtype

SIZE_PX = 64
STEPS = 120


def _tiny_images(rng, count=8):
    images, truth = [], []
    for _ in range(count):
        x = rng.uniform(0.0, 0.3, (3, SIZE_PX, SIZE_PX)).astype(np.float32)
        boxes, classes = [], []
        for _ in range(int(rng.integers(1, 4))):
            w, h = rng.integers(10, 28, 2)
            x1, y1, k = int(rng.integers(0, SIZE_PX - w)), int(rng.integers(0, SIZE_PX - h)), int(rng.integers(0, 3))
            x[k, y1:y1 + h, x1:x1 + w] = 0.9                 # the class is the colour
            boxes.append([x1, y1, x1 + w, y1 + h])
            classes.append(k)
        images.append(x)
        truth.append({"boxes": np.array(boxes, dtype=float), "classes": np.array(classes)})
    return torch.from_numpy(np.stack(images)), truth


def _rggb_packed(rgb: torch.Tensor) -> torch.Tensor:
    """Each pixel keeps its RGGB channel; the mosaic packed to 4×H/2×W/2."""
    tile = np.array([[0, 1], [1, 2]])
    idx = np.tile(tile, (SIZE_PX // 2, SIZE_PX // 2))
    mosaics = np.take_along_axis(rgb.numpy(), idx[None, None], axis=1)[:, 0]
    return torch.from_numpy(np.stack([pack_raw(m, "RGGB") for m in mosaics]))


@pytest.mark.parametrize("representation, precision, steps, images",
                         [("srgb", "fp32", STEPS, 8), ("raw", "fp32", STEPS, 8), ("srgb", "bf16", 70, 4)])
def test_mobile_overfits_tiny_images(representation, precision, steps, images):
    torch.set_num_threads(1)
    torch.manual_seed(0)
    x, truth = _tiny_images(np.random.default_rng(0), images)
    if representation == "raw":
        x = _rggb_packed(x)
    targets = collate_targets([encode_targets(t["boxes"], t["classes"], 3, (SIZE_PX, SIZE_PX)) for t in truth])
    net = build_detector("mobile", x.shape[1], 3, input_stride=2 if representation == "raw" else 1)
    opt = torch.optim.AdamW(net.parameters(), lr=3e-3, weight_decay=1e-4)
    schedule = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=3e-3, total_steps=steps, pct_start=0.1)
    dtype = autocast_dtype("cpu", precision)
    net.train()
    for _ in range(steps):
        with autocast("cpu", dtype):
            out = net(x)
        loss, _ = centernet_loss({k: v.float() for k, v in out.items()}, targets)
        opt.zero_grad()
        loss.backward()
        opt.step()
        schedule.step()
    net.eval()
    with torch.no_grad(), autocast("cpu", dtype):
        out = net(x)
    detections = decode({k: v.float() for k, v in out.items()})
    result = evaluate_map(detections, truth, ["red", "green", "blue"])
    assert result.mean_ap > 0.95, result.ap

"""CenterNet "objects as points" (Zhou et al. 2019): targets, loss and decoding shared by every detector.

A network returns, at output stride 4 in ORIGINAL image pixels (h = ceil(H/4), w = ceil(W/4)):
    heatmap  B×K×h×w  logits of "an object of class k is centred in this cell"
    size     B×2×h×w  box (width, height) in output cells (pixels / stride)
    offset   B×2×h×w  (dx, dy) of the true centre inside its cell, in cells (0…1)
The loss is the penalty-reduced focal loss on the heat-map (α = 2, β = 4) plus L1 on size
(weight 0.1) and offset (weight 1), read only at the object centres. Ignored boxes (see
workbench.detect.boxes) are no target at all: they have no centre, and the heat-map cells of
their class whose centre point lies inside one carry no negative loss (the `ignore` map) —
exactly the cells where a detection would be dropped by evaluation's rule. Decoding keeps the 3×3
max-pool peaks of sigmoid(heatmap). Everything here runs on the tensors' own device.

Boxes are (x1, y1, x2, y2) in image pixels with pixel edges at integers: a box covering pixel
columns 0…9 is x1 = 0, x2 = 10.
"""
from __future__ import annotations

import math

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from workbench.detect.boxes import centres_inside
from workbench.errors import ParameterError

OUTPUT_STRIDE_PX = 4
HEATMAP_PRIOR = 0.01          # initial sigmoid of every heat-map cell (the focal-loss prior)
FOCAL_ALPHA, FOCAL_BETA = 2.0, 4.0
SIZE_WEIGHT, OFFSET_WEIGHT = 0.1, 1.0
GAUSSIAN_MIN_OVERLAP = 0.7    # a box displaced by the Gaussian radius still overlaps the truth by this IoU
MAX_OBJECTS = 128             # per image; encode_targets refuses more


def init_heatmap_bias(conv: nn.Conv2d, prior: float = HEATMAP_PRIOR) -> None:
    """Set the heat-map output bias so sigmoid(logit) = prior everywhere at the start of training."""
    nn.init.constant_(conv.bias, -math.log((1.0 - prior) / prior))


def output_hw(image_hw: tuple[int, int], stride: int = OUTPUT_STRIDE_PX) -> tuple[int, int]:
    """Output grid (h, w) of an image of image_hw pixels: ceil of each side / stride."""
    return -(-int(image_hw[0]) // stride), -(-int(image_hw[1]) // stride)


def gaussian_radius(height: float, width: float, min_overlap: float = GAUSSIAN_MIN_OVERLAP) -> float:
    """Largest corner displacement r (same units as the box) keeping IoU ≥ min_overlap with the box.

    The smallest root over CornerNet's three cases (both corners inside, both outside, one of
    each), each the positive root of a quadratic a·r² + b·r + c = 0 solved exactly (CornerNet's
    code divides by 2 instead of 2a, which over-sizes the first two cases)."""
    h, w, o = float(height), float(width), float(min_overlap)
    cases = ((1.0, -(h + w), w * h * (1 - o) / (1 + o)),
             (4.0, -2 * (h + w), (1 - o) * w * h),
             (4 * o, 2 * o * (h + w), (o - 1) * w * h))
    roots = []
    for a, b, c in cases:
        disc = max(b * b - 4 * a * c, 0.0)
        roots.append((-b - math.sqrt(disc)) / (2 * a) if c > 0 else (-b + math.sqrt(disc)) / (2 * a))
    return max(0.0, min(roots))


def _draw_gaussian(heatmap: np.ndarray, cx: int, cy: int, radius: int) -> None:
    """heatmap = max(heatmap, exp(−d²/2σ²)) in a (2r+1)² window at (cx, cy), σ = (2r+1)/6; peak 1."""
    sigma = (2 * radius + 1) / 6.0
    d = np.arange(-radius, radius + 1, dtype=np.float64)
    g = np.exp(-(d[:, None] ** 2 + d[None, :] ** 2) / (2 * sigma * sigma)).astype(np.float32)
    h, w = heatmap.shape
    top, bottom = min(cy, radius), min(h - cy, radius + 1)
    left, right = min(cx, radius), min(w - cx, radius + 1)
    window = heatmap[cy - top:cy + bottom, cx - left:cx + right]
    np.maximum(window, g[radius - top:radius + bottom, radius - left:radius + right], out=window)


def ignore_map(boxes_xyxy, classes, num_classes: int, out_hw: tuple[int, int], stride: int = OUTPUT_STRIDE_PX
               ) -> np.ndarray:
    """K×h×w float32: 1 in the output cells of class k whose centre point lies inside an ignored
    box of class k (boxes.centres_inside). Cell (r, c) decodes to box centres (c + dx, r + dy)·stride,
    offsets in [0, 1) (`decode`); its centre point is ((c + ½)·stride, (r + ½)·stride)."""
    h, w = out_hw
    rows, cols = np.meshgrid((np.arange(h) + 0.5) * stride, (np.arange(w) + 0.5) * stride, indexing="ij")
    points = np.stack([cols.ravel(), rows.ravel()], axis=1)
    boxes = np.asarray(boxes_xyxy, np.float64).reshape(-1, 4)
    labels = np.asarray(classes, np.int64).reshape(-1)
    out = np.zeros((num_classes, h, w), dtype=np.float32)
    for k in np.unique(labels):
        out[k] = centres_inside(points, boxes[labels == k]).any(axis=1).reshape(h, w)
    return out


def encode_targets(boxes_xyxy, classes, num_classes: int, image_hw: tuple[int, int],
                   stride: int = OUTPUT_STRIDE_PX, max_objects: int = MAX_OBJECTS,
                   ignored_xyxy=None, ignored_classes=None) -> dict[str, torch.Tensor]:
    """Training targets of one image (CPU tensors; stack a batch with collate_targets).

    boxes_xyxy: N×4 in image pixels (clipped to the image here); classes: N ints in [0, num_classes);
    ignored_xyxy, ignored_classes: the image's ignored boxes (none by default).
    Returns heatmap K×h×w (a Gaussian of radius gaussian_radius at each centre cell, peak 1),
    ignore K×h×w (ignore_map), size M×2 and offset M×2 (in cells, as the network predicts them),
    index M (flat cell y·w + x) and mask M (1 for the first N rows) with M = max_objects."""
    boxes = np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4)
    labels = np.asarray(classes, dtype=np.int64).reshape(-1)
    if labels.size != boxes.shape[0]:
        raise ParameterError("classes", labels.size, f"one class per box ({boxes.shape[0]} boxes)")
    if labels.size > max_objects:
        raise ParameterError("boxes", labels.size, f"at most max_objects = {max_objects} per image")
    if labels.size and (labels.min() < 0 or labels.max() >= num_classes):
        raise ParameterError("classes", labels.tolist(), f"integers in [0, {num_classes})")
    img_h, img_w = int(image_hw[0]), int(image_hw[1])
    h, w = output_hw((img_h, img_w), stride)
    boxes = np.clip(boxes, 0.0, [img_w, img_h, img_w, img_h])
    sizes = boxes[:, 2:] - boxes[:, :2]
    if np.any(sizes <= 0) or not np.all(np.isfinite(boxes)):
        bad = int(np.flatnonzero(np.any(sizes <= 0, axis=1) | ~np.all(np.isfinite(boxes), axis=1))[0])
        raise ParameterError(f"boxes[{bad}]", boxes[bad].tolist(), "x1 < x2 and y1 < y2 inside the image")

    heatmap = np.zeros((num_classes, h, w), dtype=np.float32)
    size = np.zeros((max_objects, 2), dtype=np.float32)
    offset = np.zeros((max_objects, 2), dtype=np.float32)
    index = np.zeros(max_objects, dtype=np.int64)
    mask = np.zeros(max_objects, dtype=np.float32)
    centres = (boxes[:, :2] + boxes[:, 2:]) / (2.0 * stride)
    for i, (k, (cx, cy), (bw, bh)) in enumerate(zip(labels, centres, sizes / stride)):
        ix, iy = min(int(cx), w - 1), min(int(cy), h - 1)
        _draw_gaussian(heatmap[k], ix, iy, int(gaussian_radius(bh, bw)))
        size[i] = bw, bh
        offset[i] = cx - ix, cy - iy
        index[i] = iy * w + ix
        mask[i] = 1.0
    ignore = ignore_map(np.zeros((0, 4)) if ignored_xyxy is None else ignored_xyxy,
                        np.zeros(0, np.int64) if ignored_classes is None else ignored_classes, num_classes, (h, w), stride)
    return {"heatmap": torch.from_numpy(heatmap), "ignore": torch.from_numpy(ignore), "size": torch.from_numpy(size),
            "offset": torch.from_numpy(offset), "index": torch.from_numpy(index), "mask": torch.from_numpy(mask)}


def collate_targets(targets: list[dict[str, torch.Tensor]]) -> dict[str, torch.Tensor]:
    """Stack per-image targets into a batch (move it with {k: v.to(device) for k, v in …})."""
    return {key: torch.stack([t[key] for t in targets]) for key in targets[0]}


def focal_loss(logits: torch.Tensor, target: torch.Tensor, ignore: torch.Tensor | None = None) -> torch.Tensor:
    """Penalty-reduced focal loss, summed and divided by the number of peaks (cells where target = 1).

    Positives: −(1 − p)^α log p; others: −(1 − y)^β p^α log(1 − p) · (1 − ignore), with
    log p = logsigmoid(x) (numerically exact where the clamped-sigmoid form is not)."""
    p = torch.sigmoid(logits)
    positive = target.eq(1).to(logits.dtype)
    pos = (1 - p).pow(FOCAL_ALPHA) * F.logsigmoid(logits) * positive
    negative = 1 - positive if ignore is None else (1 - positive) * (1 - ignore)
    neg = (1 - target).pow(FOCAL_BETA) * p.pow(FOCAL_ALPHA) * F.logsigmoid(-logits) * negative
    return -(pos.sum() + neg.sum()) / positive.sum().clamp(min=1.0)


def _at_centres(maps: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """B×2×h×w maps read at B×M flat cell indices → B×M×2."""
    b, c = maps.shape[:2]
    return maps.reshape(b, c, -1).gather(2, index.unsqueeze(1).expand(b, c, index.shape[1])).transpose(1, 2)


def _masked_l1(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean absolute error over the objects (mask B×M) and both components."""
    return ((pred - target).abs() * mask.unsqueeze(2)).sum() / (2.0 * mask.sum().clamp(min=1.0))


def centernet_loss(outputs: dict[str, torch.Tensor], targets: dict[str, torch.Tensor]
                   ) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """(total, {"heatmap", "size", "offset"}) for a batch; the parts are detached scalar tensors.

    total = focal(heatmap) + 0.1 · L1(size) + 1 · L1(offset), targets from collate_targets on the
    outputs' device."""
    if outputs["heatmap"].shape != targets["heatmap"].shape:
        raise ParameterError("targets['heatmap']", tuple(targets["heatmap"].shape),
                             f"the network's heat-map shape {tuple(outputs['heatmap'].shape)} "
                             "(encode with the input image's size and stride 4)")
    out = {key: outputs[key].float() for key in ("heatmap", "size", "offset")}   # float32 also under autocast
    heat = focal_loss(out["heatmap"], targets["heatmap"], targets.get("ignore"))
    size = _masked_l1(_at_centres(out["size"], targets["index"]), targets["size"], targets["mask"])
    offset = _masked_l1(_at_centres(out["offset"], targets["index"]), targets["offset"], targets["mask"])
    total = heat + SIZE_WEIGHT * size + OFFSET_WEIGHT * offset
    return total, {"heatmap": heat.detach(), "size": size.detach(), "offset": offset.detach()}


@torch.no_grad()
def decode(outputs: dict[str, torch.Tensor], stride: int = OUTPUT_STRIDE_PX, k: int = 100,
           score_threshold: float = 0.01) -> list[dict[str, np.ndarray]]:
    """Detections per image: dict(boxes N×4 xyxy image px float32, scores N, classes N int64), numpy.

    Peaks are cells equal to the 3×3 max-pool of sigmoid(heatmap); the k best peaks over all
    classes are kept, then those with score ≥ score_threshold, best first. Sizes below zero
    count as zero."""
    heat = torch.sigmoid(outputs["heatmap"].float())
    b, num_classes, h, w = heat.shape
    peaks = heat * (F.max_pool2d(heat, 3, stride=1, padding=1) == heat)
    scores, flat = peaks.reshape(b, -1).topk(min(k, num_classes * h * w), dim=1)
    classes, cell = flat // (h * w), flat % (h * w)
    size = _at_centres(outputs["size"].float(), cell).clamp(min=0.0)
    offset = _at_centres(outputs["offset"].float(), cell)
    centre = torch.stack([cell % w, cell // w], dim=2).to(heat.dtype) + offset
    boxes = torch.cat([centre - size / 2, centre + size / 2], dim=2) * stride
    result = []
    for i in range(b):
        keep = scores[i] >= score_threshold
        result.append({"boxes": boxes[i][keep].cpu().numpy(), "scores": scores[i][keep].cpu().numpy(),
                       "classes": classes[i][keep].cpu().numpy()})
    return result

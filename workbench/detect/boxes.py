"""Boxes of the detection study, and the one rule that says which of them count (numpy only).

Boxes are (x0, y0, x1, y1) in image pixels with pixel edges at integers. A box of a detector
class is either *kept* (a training target and ground truth) or *ignored* (neither). One rule says
what an ignored box does, by the point a detection is centred on (`centres_inside`): a detection
of its class centred inside it and matched to no kept box is neither a true nor a false positive
(workbench.detect.evaluate), and the output cells of its class whose centre lies inside it carry
no training loss (workbench.detect.centernet.ignore_map). The rule for which boxes are kept
(`keep_box`), KITTI's 'moderate' level scaled to the image:

    visible height ≥ MIN_BOX_HEIGHT_FRAC of the image rows (25 px of 375: 16 px at 240 rows),
    width ≥ MIN_BOX_WIDTH_PX, occlusion ≤ MAX_OCCLUSION, truncation ≤ MAX_TRUNCATION.

A training crop applies the same rule to what it leaves of a box (`crop_boxes`): the part
outside the window adds to the box's truncation, and a kept box whose remainder fails the rule
becomes ignored, so a sliver of a road user is never trained as background.
"""
from __future__ import annotations

import numpy as np

MIN_BOX_HEIGHT_FRAC = 25.0 / 375.0
MIN_BOX_WIDTH_PX = 4
MAX_OCCLUSION = 0.8
MAX_TRUNCATION = 0.5


def keep_box(ann: dict, image_rows: int) -> bool:
    """The rule above for one COCO annotation (bbox x, y, w, h; occlusion and truncation 0…1)."""
    _, _, w, h = ann["bbox"]
    return passes_rule(h, w, ann.get("occlusion", 0.0), ann.get("truncation", 0.0), image_rows)


def passes_rule(height_px, width_px, occlusion, truncation, image_rows: int):
    """The rule above, elementwise on arrays (or scalars)."""
    return ((np.asarray(height_px) >= MIN_BOX_HEIGHT_FRAC * image_rows) & (np.asarray(width_px) >= MIN_BOX_WIDTH_PX)
            & (np.asarray(occlusion) <= MAX_OCCLUSION) & (np.asarray(truncation) <= MAX_TRUNCATION))


def box_iou(a, b) -> np.ndarray:
    """N×M IoU of xyxy boxes (float64; 0 where boxes do not overlap or have no area)."""
    a = np.asarray(a, dtype=np.float64).reshape(-1, 4)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 4)
    w = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0])
    h = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1])
    inter = np.where((w > 0) & (h > 0), w * h, 0.0)
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    union = area_a[:, None] + area_b[None, :] - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(union > 0, inter / union, 0.0)


def centres_inside(points_xy, boxes) -> np.ndarray:
    """N×M: whether point i (x, y in pixels) lies in box j, half-open [x0, x1) × [y0, y1) as the
    pixel-edge convention has it (a point on a box's right or bottom edge is in the next pixel)."""
    p = np.asarray(points_xy, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    x, y = p[:, 0, None], p[:, 1, None]
    return (b[None, :, 0] <= x) & (x < b[None, :, 2]) & (b[None, :, 1] <= y) & (y < b[None, :, 3])


def mirror_boxes(boxes: np.ndarray, width_px: int) -> np.ndarray:
    """Boxes of the left–right mirror image of an image width_px wide."""
    out = np.array(boxes, dtype=np.float32).reshape(-1, 4)
    out[:, 0], out[:, 2] = width_px - out[:, 2], width_px - out[:, 0]
    return out


def crop_boxes(boxes: np.ndarray, classes: np.ndarray, truncation: np.ndarray, top_px: int, left_px: int,
               height_px: int, width_px: int, image_rows: int):
    """Kept boxes after cutting the window (top, left, height, width) out of the image.

    Returns (kept boxes, kept classes, kept truncations, newly ignored boxes, their classes), in
    window coordinates, clipped to it. A box's truncation grows by the part of it outside the
    window: 1 − (1 − t)·a_in/a. Boxes left with no area inside are dropped; boxes whose remainder
    fails the rule (too short, too narrow or too truncated) are returned as ignored."""
    boxes = np.asarray(boxes, dtype=np.float32).reshape(-1, 4)
    moved = boxes - np.asarray([left_px, top_px, left_px, top_px], np.float32)
    inside = moved.copy()
    inside[:, [0, 2]] = inside[:, [0, 2]].clip(0, width_px)
    inside[:, [1, 3]] = inside[:, [1, 3]].clip(0, height_px)
    w_in, h_in = inside[:, 2] - inside[:, 0], inside[:, 3] - inside[:, 1]
    area = np.maximum((moved[:, 2] - moved[:, 0]) * (moved[:, 3] - moved[:, 1]), 1e-12)
    seen = (w_in > 0) & (h_in > 0)
    trunc = 1.0 - (1.0 - np.asarray(truncation, np.float32)) * np.where(seen, w_in * h_in, 0.0) / area
    keep = seen & passes_rule(h_in, w_in, 0.0, trunc, image_rows)
    lost = seen & ~keep
    classes = np.asarray(classes)
    return inside[keep], classes[keep], trunc[keep].astype(np.float32), inside[lost], classes[lost]


def clip_boxes(boxes: np.ndarray, classes: np.ndarray, top_px: int, left_px: int, height_px: int,
               width_px: int) -> tuple[np.ndarray, np.ndarray]:
    """Ignored boxes in a window: shifted, clipped, and dropped when nothing of them is inside."""
    moved = np.asarray(boxes, np.float32).reshape(-1, 4) - np.asarray([left_px, top_px, left_px, top_px], np.float32)
    moved[:, [0, 2]] = moved[:, [0, 2]].clip(0, width_px)
    moved[:, [1, 3]] = moved[:, [1, 3]].clip(0, height_px)
    seen = (moved[:, 2] > moved[:, 0]) & (moved[:, 3] > moved[:, 1])
    return moved[seen], np.asarray(classes)[seen]


def crop_corner(boxes: np.ndarray, image_hw: tuple[int, int], crop_hw: tuple[int, int],
                rng: np.random.Generator) -> tuple[int, int]:
    """Even (row, col) corner of a crop window: uniform among the windows that hold the centre of
    one kept box drawn at random (uniform over the image when there is none); even offsets keep
    the CFA phase."""
    (h, w), (ch, cw) = image_hw, crop_hw
    lo_r, hi_r, lo_c, hi_c = 0, h - ch, 0, w - cw
    if len(boxes):
        x0, y0, x1, y1 = boxes[int(rng.integers(len(boxes)))]
        cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
        lo_r, hi_r = max(0, int(np.ceil(cy - ch + 1))), min(h - ch, int(cy))
        lo_c, hi_c = max(0, int(np.ceil(cx - cw + 1))), min(w - cw, int(cx))
    r0 = 2 * int(rng.integers((lo_r + 1) // 2, hi_r // 2 + 1)) if hi_r >= lo_r + 1 else 2 * (hi_r // 2)
    c0 = 2 * int(rng.integers((lo_c + 1) // 2, hi_c // 2 + 1)) if hi_c >= lo_c + 1 else 2 * (hi_c // 2)
    return r0, c0

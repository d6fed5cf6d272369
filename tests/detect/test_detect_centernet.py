"""CenterNet targets, loss and decoding: encoded ground truth decodes back to itself."""
import math

import numpy as np
import pytest
import torch

from workbench.detect.centernet import (
    HEATMAP_PRIOR, centernet_loss, collate_targets, decode, encode_targets, focal_loss, gaussian_radius,
    output_hw)
from workbench.errors import ParameterError

from detect_helpers import perfect_outputs, random_boxes


def test_encoded_ground_truth_decodes_to_itself():
    rng = np.random.default_rng(0)
    image_hw = (96, 128)
    batch = []
    for _ in range(6):
        boxes = random_boxes(rng, 8, image_hw)
        cells = np.floor((boxes[:, :2] + boxes[:, 2:]) / 8).astype(int)   # centre cells (stride 4)
        _, first = np.unique(cells, axis=0, return_index=True)            # one object per centre cell
        boxes = boxes[np.sort(first)]
        batch.append((boxes, rng.integers(0, 3, len(boxes))))
    targets = collate_targets([encode_targets(b, c, 3, image_hw) for b, c in batch])
    assert targets["heatmap"].shape == (6, 3, 24, 32)
    for (boxes, classes), det in zip(batch, decode(perfect_outputs(targets))):
        assert len(det["boxes"]) == len(boxes)
        order = np.lexsort(boxes.T[::-1])
        got = np.lexsort(det["boxes"].T[::-1])
        np.testing.assert_allclose(det["boxes"][got], boxes[order], atol=1e-4)
        assert np.array_equal(det["classes"][got], classes[order])
        np.testing.assert_allclose(det["scores"], 1.0, atol=1e-5)


def test_targets_layout():
    t = encode_targets([[8.0, 4.0, 24.0, 12.0]], [1], 2, (30, 41))
    assert output_hw((30, 41)) == (8, 11) and t["heatmap"].shape == (2, 8, 11)
    # centre (16, 8) px = cell (4, 2) exactly, offset 0; size 16×8 px = 4×2 cells
    assert t["index"][0] == 2 * 11 + 4 and t["mask"].sum() == 1
    assert t["heatmap"][1, 2, 4] == 1.0 and t["heatmap"][0].sum() == 0
    np.testing.assert_allclose(t["size"][0], [4, 2])
    np.testing.assert_allclose(t["offset"][0], [0, 0])


def test_gaussian_radius_keeps_overlap():
    """A box whose corners move by the radius still overlaps the original by IoU ≥ 0.7 (all three cases)."""
    for h, w in ((10, 10), (3, 40), (50, 7)):
        r = gaussian_radius(h, w)
        shifted = (w - r) * (h - r) / (2 * w * h - (w - r) * (h - r))
        shrunk = (w - 2 * r) * (h - 2 * r) / (w * h)
        grown = w * h / ((w + 2 * r) * (h + 2 * r))
        assert min(shifted, shrunk, grown) == pytest.approx(0.7, abs=1e-9)


def test_bad_boxes_refused():
    with pytest.raises(ParameterError, match="boxes\\[1\\]"):
        encode_targets([[0, 0, 4, 4], [5, 5, 5, 9]], [0, 0], 1, (16, 16))
    with pytest.raises(ParameterError, match="classes"):
        encode_targets([[0, 0, 4, 4]], [3], 2, (16, 16))


def test_focal_loss_closed_form():
    """One positive and one negative cell: the formula by hand."""
    logits = torch.tensor([[[[0.3, -1.2]]]])
    target = torch.tensor([[[[1.0, 0.5]]]])
    p = torch.sigmoid(logits)[0, 0, 0]
    expected = -((1 - p[0]) ** 2 * math.log(p[0]) + (1 - 0.5) ** 4 * p[1] ** 2 * math.log(1 - p[1]))
    assert focal_loss(logits, target).item() == pytest.approx(expected.item(), rel=1e-6)


def test_loss_is_small_for_perfect_outputs_and_empty_images_work():
    rng = np.random.default_rng(1)
    targets = collate_targets([encode_targets(random_boxes(rng, 3, (64, 64)), [0, 1, 2], 3, (64, 64)),
                               encode_targets(np.zeros((0, 4)), [], 3, (64, 64))])
    total, parts = centernet_loss(perfect_outputs(targets), targets)
    assert parts["size"].item() < 1e-6 and parts["offset"].item() < 1e-6 and total.item() < 1e-3
    prior = {"heatmap": torch.full((2, 3, 16, 16), math.log(HEATMAP_PRIOR / (1 - HEATMAP_PRIOR))),
             "size": torch.zeros(2, 2, 16, 16), "offset": torch.zeros(2, 2, 16, 16)}
    total, _ = centernet_loss(prior, targets)
    assert math.isfinite(total.item()) and total.item() > 1
    assert decode(prior, score_threshold=0.02)[1]["boxes"].shape == (0, 4)


def test_ignored_boxes_carry_no_loss_of_their_class():
    """A confident detection on an ignored road user costs nothing in its class (it is neither a
    positive nor a negative target) but still counts as a false alarm for the other classes."""
    kept, ignored = [[4, 4, 20, 28]], [[40, 8, 52, 24]]              # 64×64 image: output cells 16×16
    targets = collate_targets([encode_targets(kept, [0], 2, (64, 64), ignored_xyxy=ignored, ignored_classes=[1])])
    ignore = targets["ignore"][0]
    assert ignore[1, 2:6, 10:13].eq(1).all() and ignore[1].sum() == 12 and ignore[0].sum() == 0
    base = perfect_outputs(targets)
    for k, cost in ((1, 0.0), (0, None)):
        fired = {key: v.clone() for key, v in base.items()}
        fired["heatmap"][0, k, 2:6, 10:13] = 6.0                     # p ≈ 0.998 over the ignored box
        extra = (centernet_loss(fired, targets)[1]["heatmap"] - centernet_loss(base, targets)[1]["heatmap"]).item()
        if cost is not None:
            assert extra == pytest.approx(cost, abs=1e-9)
        else:
            assert extra > 1.0                                      # class 0 is not ignored there
    unmasked = {k: v for k, v in targets.items() if k != "ignore"}
    fired = {key: v.clone() for key, v in base.items()}
    fired["heatmap"][0, 1, 2:6, 10:13] = 6.0
    assert centernet_loss(fired, unmasked)[1]["heatmap"] > centernet_loss(base, unmasked)[1]["heatmap"] + 1.0

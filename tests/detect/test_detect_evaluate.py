"""mAP: the ground-truth oracle gives 1, COCO 101-point equals pycocotools, VOC all-point by hand."""
import math

import numpy as np
import pytest

from workbench.detect.centernet import collate_targets, decode, encode_targets
from workbench.detect.evaluate import (
    ap_voc_all_point, box_iou, evaluate_map, precision_recall, pycocotools_ap50)
from workbench.errors import ParameterError

from detect_helpers import perfect_outputs, random_boxes

NAMES = ["car", "pedestrian", "bus"]


def test_encoded_ground_truth_decodes_to_ap_one():
    rng = np.random.default_rng(5)
    image_hw = (120, 160)
    truth = []
    for _ in range(10):
        boxes = random_boxes(rng, 6, image_hw, min_px=8)
        _, first = np.unique(np.floor((boxes[:, :2] + boxes[:, 2:]) / 8), axis=0, return_index=True)
        boxes = boxes[np.sort(first)]
        truth.append({"boxes": boxes, "classes": rng.integers(0, 3, len(boxes))})
    targets = collate_targets([encode_targets(t["boxes"], t["classes"], 3, image_hw) for t in truth])
    result = evaluate_map(decode(perfect_outputs(targets)), truth, NAMES)
    assert result.mean_ap == 1.0 and all(v == 1.0 for v in result.ap.values())


def _random_case(rng):
    """Images with jittered copies of the truth, random boxes, tied scores, empty images, a missing class."""
    n_images = int(rng.integers(1, 6))
    missing = int(rng.integers(0, 3)) if rng.random() < 0.5 else None
    det, gt = [], []
    for _ in range(n_images):
        n_gt = 0 if rng.random() < 0.2 else int(rng.integers(1, 8))
        g_boxes = random_boxes(rng, n_gt, (100, 100), min_px=4)
        g_cls = rng.integers(0, 3, n_gt)
        if missing is not None:
            g_cls[g_cls == missing] = (missing + 1) % 3
        n_dup = n_gt * int(rng.integers(0, 3))
        dup = np.repeat(g_boxes, int(n_dup / max(n_gt, 1)), axis=0) + rng.normal(0, 3, (n_dup, 4))
        dup[:, 2:] = np.maximum(dup[:, 2:], dup[:, :2] + 1)
        n_rand = int(rng.choice([0, 5, 40, 400]))       # > 100 detections of one class in some images
        boxes = np.concatenate([dup, random_boxes(rng, n_rand, (100, 100), min_px=4)])
        classes = np.concatenate([np.repeat(g_cls, int(n_dup / max(n_gt, 1))), rng.integers(0, 3, n_rand)])
        scores = np.concatenate([rng.uniform(0.3, 1.0, n_dup), rng.uniform(0.0, 0.8, n_rand)])
        if rng.random() < 0.5:
            scores = np.round(scores, 1)                           # many tied scores
        if rng.random() < 0.1:
            boxes, classes, scores = np.zeros((0, 4)), np.zeros(0, int), np.zeros(0)   # no detections
        det.append({"boxes": boxes, "classes": classes, "scores": scores})
        gt.append({"boxes": g_boxes, "classes": g_cls})
    return det, gt


@pytest.mark.parametrize("max_detections", [100, 10**6])
def test_coco_101_point_equals_pycocotools(max_detections):
    rng = np.random.default_rng(7)
    compared = 0
    for _ in range(30):
        det, gt = _random_case(rng)
        ours = evaluate_map(det, gt, NAMES, method="coco101", max_detections=max_detections)
        ref = pycocotools_ap50(det, gt, NAMES, max_detections=max_detections)
        for name in NAMES:
            if math.isnan(ref["ap"][name]):
                assert math.isnan(ours.ap[name])
            else:
                assert abs(ours.ap[name] - ref["ap"][name]) < 1e-9
                compared += 1
        assert (math.isnan(ours.mean_ap) and math.isnan(ref["mean_ap"])) or abs(ours.mean_ap - ref["mean_ap"]) < 1e-9
    assert compared > 60


def test_voc_all_point_by_hand():
    """3 truths; ranks TP, FP, TP, FP: recall 1/3, 1/3, 2/3, 2/3; precision 1, 1/2, 2/3, 1/2 → AP 1/3 + 1/3·2/3."""
    gt = [{"boxes": [[0, 0, 10, 10], [20, 0, 30, 10], [40, 0, 50, 10]], "classes": [0, 0, 0]}]
    det = [{"boxes": [[0, 0, 10, 10], [60, 0, 70, 10], [20, 0, 30, 10], [80, 0, 90, 10]],
            "scores": [0.9, 0.8, 0.7, 0.6], "classes": [0, 0, 0, 0]}]
    result = evaluate_map(det, gt, ["car"])
    assert result.ap["car"] == pytest.approx(5 / 9, abs=1e-12)
    # COCO samples the same envelope at 101 recalls: 34 at precision 1, 33 at 2/3, 34 at 0
    assert evaluate_map(det, gt, ["car"], method="coco101").ap["car"] == pytest.approx((34 + 33 * 2 / 3) / 101)


def test_voc_all_point_equals_mean_interpolated_precision_at_each_true_positive():
    """All-point AP = (1/n_gt) Σ over true positives of the best precision at that rank or later."""
    rng = np.random.default_rng(9)
    for _ in range(100):
        tp = rng.random(int(rng.integers(1, 60))) < rng.random()
        n_gt = int(tp.sum() + rng.integers(0, 5)) or 1
        ranks = np.arange(1, tp.size + 1)
        precision = np.cumsum(tp) / ranks
        recall = np.cumsum(tp) / n_gt
        expected = sum(precision[i:].max() for i in np.flatnonzero(tp)) / n_gt
        assert ap_voc_all_point(recall, precision) == pytest.approx(expected, abs=1e-12)


def test_empty_detections_give_zero_and_missing_class_is_left_out():
    gt = [{"boxes": [[0, 0, 10, 10]], "classes": [0]}, {"boxes": np.zeros((0, 4)), "classes": []}]
    det = [{"boxes": np.zeros((0, 4)), "scores": [], "classes": []}] * 2
    result = evaluate_map(det, gt, ["car", "bus"])
    assert result.ap["car"] == 0.0 and math.isnan(result.ap["bus"]) and result.mean_ap == 0.0
    assert result.notes == ["no ground truth for bus: left out of the mean"]
    assert pycocotools_ap50(det, gt, ["car", "bus"])["ap"]["car"] == 0.0
    payload = result.to_dict()
    assert payload["ap"]["bus"] is None and payload["curves"]["car"] == {"recall": [], "precision": []}


def test_matching_takes_the_free_box_and_mismatched_lengths_fail():
    # two overlapping truths; the second detection's best box is taken, the other one is still ≥ 0.5
    gt = [{"boxes": [[0, 0, 10, 10], [1, 0, 11, 10]], "classes": [0, 0]}]
    det = [{"boxes": [[0, 0, 10, 10], [0.5, 0, 10.5, 10]], "scores": [0.9, 0.8], "classes": [0, 0]}]
    recall, precision, n = precision_recall(det, gt, 0)
    assert n == 2 and recall.tolist() == [0.5, 1.0] and precision.tolist() == [1.0, 1.0]
    assert box_iou([[0, 0, 10, 10]], [[5, 0, 15, 10]])[0, 0] == pytest.approx(1 / 3)
    with pytest.raises(ParameterError, match="scores"):
        evaluate_map([{"boxes": [[0, 0, 1, 1]], "scores": [], "classes": [0]}], gt, ["car"])

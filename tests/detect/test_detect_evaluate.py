"""mAP: the ground-truth oracle gives 1, COCO 101-point equals pycocotools, VOC all-point by hand; the
ignore rule against a per-detection oracle, pycocotools' crowd boxes and the training mask."""
import math

import numpy as np
import pytest
import torch

from workbench.detect.centernet import collate_targets, decode, encode_targets
from workbench.detect.evaluate import (
    ap_voc_all_point, bootstrap_weights, box_iou, evaluate_map, match_table, precision_recall, pycocotools_ap50)
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


def _same_ap_per_class(ours, ref) -> int:
    """Assert our AP equals pycocotools' per class (NaN where it has none); the classes compared."""
    compared = 0
    for name in NAMES:
        if math.isnan(ref["ap"][name]):
            assert math.isnan(ours.ap[name])
        else:
            assert abs(ours.ap[name] - ref["ap"][name]) < 1e-9
            compared += 1
    return compared


@pytest.mark.parametrize("max_detections", [100, 10**6])
def test_coco_101_point_equals_pycocotools(max_detections):
    rng = np.random.default_rng(7)
    compared = 0
    for _ in range(30):
        det, gt = _random_case(rng)
        ours = evaluate_map(det, gt, NAMES, method="coco101", max_detections=max_detections)
        ref = pycocotools_ap50(det, gt, NAMES, max_detections=max_detections)
        compared += _same_ap_per_class(ours, ref)
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


def test_detection_centred_in_a_small_ignored_box_is_neither_true_nor_false():
    """A 4×9 detection inside a 6×16 ignored pedestrian (IoU 0.375 < 0.5) ranked above the one true
    positive: dropped, AP 1 (as a false positive it would make AP 0.5)."""
    gt = [{"boxes": [[0, 0, 10, 30]], "classes": [1], "ignored_boxes": [[50, 50, 56, 66]], "ignored_classes": [1]}]
    det = [{"boxes": [[51, 53, 55, 62], [0, 0, 10, 30]], "scores": [0.9, 0.8], "classes": [1, 1]}]
    assert box_iou(det[0]["boxes"][:1], gt[0]["ignored_boxes"])[0, 0] == pytest.approx(0.375)
    for method in ("voc", "coco101"):
        assert evaluate_map(det, gt, NAMES[:2], method=method).ap["pedestrian"] == 1.0
    assert match_table(det, gt, 2).mean_ap(np.ones((1, 1)))[0] == 1.0
    without = [{"boxes": gt[0]["boxes"], "classes": gt[0]["classes"]}]
    assert evaluate_map(det, without, NAMES[:2]).ap["pedestrian"] == pytest.approx(0.5)


def test_real_boxes_are_matched_before_ignored_ones():
    """Centred in an ignored box but IoU ≥ 0.5 with a real one: a true positive; the same spot in
    another class's ignored box, or an ignored box under a second, duplicate detection: as the rule says."""
    gt = [{"boxes": [[0, 0, 20, 20]], "classes": [0], "ignored_boxes": [[5, 5, 15, 15], [40, 0, 60, 20]],
           "ignored_classes": [0, 1]}]
    det = [{"boxes": [[1, 1, 21, 21], [0, 0, 20, 20], [42, 2, 58, 18]], "scores": [0.9, 0.8, 0.7],
            "classes": [0, 0, 0]}]
    recall, precision, n = precision_recall(det, gt, 0)
    # the first takes the real box, the duplicate is dropped (centre (10, 10) in the class-0 ignored
    # box), the third is centred in a class-1 ignored box only: a false positive
    assert n == 1 and recall.tolist() == [1.0, 1.0] and precision.tolist() == [1.0, 0.5]


def _iou(a, b):
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    inter = w * h if w > 0 and h > 0 else 0.0
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


def _oracle(det, gt, names, method, max_detections=None):
    """The stated rule, one detection at a time: per image and class, in score order, take the free
    real box of highest IoU ≥ 0.5 (ties: the later); else drop it if its centre is in an ignored box
    of its class; else a false positive. Then VOC's devkit integration or COCO's 101 recalls."""
    aps = {}
    for k, name in enumerate(names):
        ranked, n_gt = [], 0
        for i, (d, g) in enumerate(zip(det, gt)):
            real = [list(b) for b, c in zip(np.reshape(g["boxes"], (-1, 4)), g["classes"]) if c == k]
            ign = [list(b) for b, c in zip(np.reshape(g.get("ignored_boxes", np.zeros((0, 4))), (-1, 4)),
                                           g.get("ignored_classes", [])) if c == k]
            n_gt += len(real)
            mine = [j for j in range(len(d["classes"])) if d["classes"][j] == k]
            mine = sorted(mine, key=lambda j: (-d["scores"][j], j))[:max_detections]
            free = [True] * len(real)
            for j in mine:
                box = list(d["boxes"][j])
                best, match = 0.5, None
                for g_i, r in enumerate(real):
                    if free[g_i] and _iou(box, r) >= best:
                        best, match = _iou(box, r), g_i
                if match is not None:
                    free[match] = False
                    ranked.append((-d["scores"][j], i, j, True))
                    continue
                cx, cy = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
                if not any(b[0] <= cx < b[2] and b[1] <= cy < b[3] for b in ign):
                    ranked.append((-d["scores"][j], i, j, False))
        if n_gt == 0:
            aps[name] = math.nan
            continue
        tp = np.array([r[3] for r in sorted(ranked)], dtype=float)
        rec = np.cumsum(tp) / n_gt
        prec = np.cumsum(tp) / np.arange(1, len(tp) + 1)
        if method == "voc":
            mrec, mpre = np.concatenate([[0.0], rec, [1.0]]), np.concatenate([[0.0], prec, [0.0]])
            for i in range(len(mpre) - 2, -1, -1):
                mpre[i] = max(mpre[i], mpre[i + 1])
            steps = np.flatnonzero(mrec[1:] != mrec[:-1])
            aps[name] = float(np.sum((mrec[steps + 1] - mrec[steps]) * mpre[steps + 1]))
        else:
            aps[name] = float(np.mean([prec[rec >= r].max() if np.any(rec >= r) else 0.0
                                       for r in np.linspace(0, 1, 101)]))
    with_gt = [v for v in aps.values() if not math.isnan(v)]
    return aps, (float(np.mean(with_gt)) if with_gt else math.nan)


def _with_ignored(rng, det, gt, coinciding=False):
    """Adds 0–4 ignored boxes per image (some tiny) and detections in, around and across them;
    coinciding: keeps only detections wholly inside an ignored box of their class or clear of
    all of them, where COCO's crowd rule (IoA ≥ 0.5) and the centre rule agree."""
    for d, g in zip(det, gt):
        n = int(rng.integers(0, 5))
        ign = random_boxes(rng, n, (100, 100), min_px=2)
        ign_cls = rng.integers(0, 3, n)
        extra_boxes, extra_cls = [], []
        for box, cls in zip(ign, ign_cls):
            for _ in range(int(rng.integers(0, 4))):
                w, h = box[2] - box[0], box[3] - box[1]
                cx = rng.uniform(box[0] - 0.3 * w, box[2] + 0.3 * w)
                cy = rng.uniform(box[1] - 0.3 * h, box[3] + 0.3 * h)
                hw, hh = rng.uniform(0.2, 1.5) * w / 2, rng.uniform(0.2, 1.5) * h / 2
                extra_boxes.append([cx - hw, cy - hh, cx + hw, cy + hh])
                extra_cls.append(cls if rng.random() < 0.8 else (cls + 1) % 3)
        boxes = np.concatenate([np.reshape(d["boxes"], (-1, 4)), np.reshape(extra_boxes, (-1, 4))])
        classes = np.concatenate([d["classes"], np.asarray(extra_cls, int)]).astype(int)
        scores = np.concatenate([d["scores"], np.round(rng.uniform(0, 1, len(extra_cls)), 2)])
        if coinciding:
            keep = []
            for box, cls in zip(boxes, classes):
                mine = ign[ign_cls == cls]
                inside = np.any((mine[:, 0] <= box[0]) & (mine[:, 1] <= box[1]) & (box[2] <= mine[:, 2])
                                & (box[3] <= mine[:, 3]))
                keep.append(inside or all(_iou(box, b) == 0 for b in mine))
            keep = np.array(keep, bool).reshape(-1)
            boxes, classes, scores = boxes[keep], classes[keep], scores[keep]
        d.update(boxes=boxes, classes=classes, scores=scores)
        g.update(ignored_boxes=ign, ignored_classes=ign_cls)
    return det, gt


def test_ignore_rule_equals_a_per_detection_oracle_and_bootstrap_table():
    rng = np.random.default_rng(11)
    images = dropped = 0
    for case in range(60):
        det, gt = _with_ignored(rng, *_random_case(rng))
        images += len(gt)
        for method, m in (("voc", None), ("coco101", None), ("coco101", 5)):
            ours = evaluate_map(det, gt, NAMES, method=method, max_detections=m)
            ref_ap, ref_mean = _oracle(det, gt, NAMES, method, m)
            for name in NAMES:
                assert (math.isnan(ours.ap[name]) and math.isnan(ref_ap[name])) or \
                    ours.ap[name] == pytest.approx(ref_ap[name], abs=1e-12), (case, method, name)
        plain = evaluate_map(det, [{"boxes": g["boxes"], "classes": g["classes"]} for g in gt], NAMES)
        dropped += sum(len(plain.curves[n][0]) - len(ours.curves[n][0]) for n in NAMES)
        # the bootstrap table: all multiplicities 1 is evaluate_map; a resample is its images repeated
        table = match_table(det, gt, 3)
        voc = evaluate_map(det, gt, NAMES).mean_ap
        assert (math.isnan(voc) and math.isnan(table.mean_ap(np.ones(len(gt)))[0])) or \
            table.mean_ap(np.ones(len(gt)))[0] == pytest.approx(voc, abs=1e-12)
        unique = [{**d, "scores": rng.permutation(len(d["scores"])) + 1000.0 * i} for i, d in enumerate(det)]
        weights = bootstrap_weights(len(gt), 3, seed=case)
        maps = match_table(unique, gt, 3).mean_ap(weights)
        for row, value in zip(weights, maps):
            picked = np.repeat(np.arange(len(gt)), row)
            expected = _oracle([unique[i] for i in picked], [gt[i] for i in picked], NAMES, "voc")[1]
            assert (math.isnan(value) and math.isnan(expected)) or value == pytest.approx(expected, abs=1e-12)
    assert images >= 150 and dropped > 100


def test_ignore_rule_equals_pycocotools_crowd_where_the_two_rules_coincide():
    rng = np.random.default_rng(13)
    compared = 0
    for _ in range(40):
        det, gt = _with_ignored(rng, *_random_case(rng), coinciding=True)
        compared += _same_ap_per_class(evaluate_map(det, gt, NAMES, method="coco101", max_detections=100),
                                       pycocotools_ap50(det, gt, NAMES, max_detections=100))
    assert compared > 60


def test_training_mask_and_evaluation_drop_the_same_cells():
    """A detection decoded from cell (r, c) of class k (offset ½, 2 cells wide) is dropped by
    evaluation exactly where ignore_map masks that cell, boxes with edges on cell centres included."""
    rng = np.random.default_rng(17)
    image_hw, stride = (64, 80), 4
    h, w = image_hw[0] // stride, image_hw[1] // stride
    masked = 0
    for case in range(12):
        n = int(rng.integers(1, 5))
        ignored = random_boxes(rng, n, image_hw, min_px=1)
        if case % 2:
            ignored = np.round(ignored / 2) * 2                     # even edges: on cell centres
            ignored[:, 2:] = np.maximum(ignored[:, 2:], ignored[:, :2] + 2)
        ignored_cls = rng.integers(0, 2, n)
        mask = encode_targets(np.zeros((0, 4)), [], 2, image_hw, ignored_xyxy=ignored,
                              ignored_classes=ignored_cls)["ignore"].numpy()
        outputs = {"heatmap": torch.zeros(1, 2, h, w), "size": torch.full((1, 2, h, w), 2.0),
                   "offset": torch.full((1, 2, h, w), 0.5)}
        dets = decode(outputs, stride=stride, k=2 * h * w, score_threshold=0.0)[0]
        assert len(dets["scores"]) == 2 * h * w
        truth = [{"boxes": np.zeros((0, 4)), "classes": [], "ignored_boxes": ignored, "ignored_classes": ignored_cls}]
        for box, score, cls in zip(dets["boxes"], dets["scores"], dets["classes"]):
            one = [{"boxes": box[None], "scores": [score], "classes": [cls]}]
            kept = len(precision_recall(one, truth, int(cls))[0])
            c, r = int((box[0] + box[2]) / 2 // stride), int((box[1] + box[3]) / 2 // stride)
            assert kept == 1 - mask[cls, r, c], (case, cls, r, c)
        masked += int(mask.sum())
    assert 0 < masked < 12 * 2 * h * w

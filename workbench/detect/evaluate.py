"""Detection accuracy: AP@0.5 per class and mAP (the paper's metric), with a pycocotools cross-check.

    result = evaluate_map(detections, ground_truth, class_names)            # VOC all-point AP@0.5
    result.ap["car"], result.mean_ap, result.curves["car"]                  # recall, precision arrays
    coco = pycocotools_ap50(detections, ground_truth, class_names)          # the same data through COCO
    table = match_table(detections, ground_truth, len(class_names))         # for test-set bootstraps
    maps = table.mean_ap(bootstrap_weights(len(ground_truth), 1000))        # 1000 resampled mAPs

detections: one dict per image with boxes N×4 (x1, y1, x2, y2 in pixels), scores N, classes N
(ints indexing class_names); ground_truth: one dict per image with boxes and classes, and
optionally its ignored boxes (ignored_boxes M×4, ignored_classes M: never ground truth).

Matching (one rule for both methods, COCO's): per image and class, detections in descending score
(ties keep their given order) each take the still-unmatched ground-truth box of highest IoU ≥ the
threshold (equal IoUs: the later box); the VOC devkit differs only in counting a detection whose
best box is already taken as false even when another box ≥ 0.5 is free. Ignored boxes come
second, as COCO's crowd boxes do: a detection left unmatched whose centre lies inside an ignored
box of its class (boxes.centres_inside) is dropped, neither true nor false positive; a detection
matched to a real box stays a true positive wherever its centre is. Training masks the same
cells (centernet.ignore_map). Over the data set the remaining detections are ranked by score
(ties: image order, then rank in the image) into a precision–recall curve, integrated by `method`:
    'voc'      all-point interpolation (VOC 2010+): Σ (r_i − r_{i−1}) · max_{j ≥ i} p_j over
               every recall step — the area under the monotone precision envelope;
    'coco101'  COCO's: the envelope sampled at the 101 recalls 0, 0.01, …, 1 (first rank whose
               recall reaches each), averaged; 0 beyond the highest recall.
The two differ by design (sampling), so the cross-check compares like with like: 'coco101' with
max_detections = M equals pycocotools' AP@0.5 with maxDets M to 1e-9 (tests; max_detections cuts
before ignored detections are dropped, as maxDets does), and 'voc' is held against closed-form
cases. pycocotools_ap50 passes ignored boxes as iscrowd = 1, and COCO drops a detection whose
area lies ≥ 50 % inside one (IoA) rather than one centred in it: the two agree where every
detection is wholly inside an ignored box or clear of all (tests), and the ignore rule is
otherwise held against a per-detection reimplementation.

A class without ground-truth boxes has AP NaN and is left out of the mean (as COCO does); a class
with ground truth and no detections has AP 0. mean_ap is NaN when no class has ground truth.

Test-set bootstrap (`MatchTable`): matching is per image, so a resample of the test images (with
replacement) keeps every detection's true/false flag; a resample is a vector of image
multiplicities, and AP on it weights each detection and ground-truth box by its image's
multiplicity. With all multiplicities 1 this is evaluate_map's 'voc' AP exactly (tests). Every
run draws the same resamples (bootstrap_weights with one seed), so the differences between two
runs on the same resamples are paired.
"""
from __future__ import annotations

import contextlib
import io
import math
from dataclasses import dataclass, field

import numpy as np

from workbench.detect.boxes import box_iou, centres_inside
from workbench.errors import ParameterError

METHODS = ("voc", "coco101")
COCO_RECALLS = np.linspace(0.0, 1.0, 101)


@dataclass
class MapResult:
    """AP per class name (NaN: no ground truth), their mean over classes with ground truth, the
    number of ground-truth boxes per class, and each class's raw precision–recall curve (recall,
    precision per rank, before the envelope)."""

    ap: dict[str, float]
    mean_ap: float
    n_ground_truth: dict[str, int]
    curves: dict[str, tuple[np.ndarray, np.ndarray]]
    method: str
    iou_threshold: float
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        """JSON-ready (NaN → None; curves as lists)."""
        def num(v: float):
            return None if math.isnan(v) else float(v)
        return {"method": self.method, "iou_threshold": self.iou_threshold, "mean_ap": num(self.mean_ap),
                "ap": {k: num(v) for k, v in self.ap.items()}, "n_ground_truth": self.n_ground_truth,
                "curves": {k: {"recall": r.tolist(), "precision": p.tolist()} for k, (r, p) in self.curves.items()},
                "notes": self.notes}


def _match_image(det_boxes: np.ndarray, gt_boxes: np.ndarray, ignored_boxes: np.ndarray,
                 iou_threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """(true-positive flag, dropped flag) of each detection (already in rank order) under the
    module's matching rule: real boxes first, then the ignored boxes' centre rule."""
    tp = np.zeros(len(det_boxes), dtype=bool)
    if len(gt_boxes) and len(det_boxes):
        ious = box_iou(det_boxes, gt_boxes)
        taken = np.zeros(len(gt_boxes), dtype=bool)
        for d in range(len(det_boxes)):
            best, match = min(iou_threshold, 1 - 1e-10), -1
            for g in range(len(gt_boxes)):
                if not taken[g] and ious[d, g] >= best:
                    best, match = ious[d, g], g
            if match >= 0:
                taken[match], tp[d] = True, True
    centres = 0.5 * (det_boxes[:, :2] + det_boxes[:, 2:])
    return tp, ~tp & centres_inside(centres, ignored_boxes).any(axis=1)


def _class_arrays(item: dict, cls: int, need_scores: bool):
    classes = np.asarray(item.get("classes", []), dtype=np.int64).reshape(-1)
    boxes = np.asarray(item.get("boxes", np.zeros((0, 4))), dtype=np.float64).reshape(-1, 4)
    if len(boxes) != len(classes):
        raise ParameterError("boxes", len(boxes), f"one box per class label ({len(classes)} labels)")
    on = classes == cls
    if not need_scores:
        return boxes[on], None
    scores = np.asarray(item.get("scores", []), dtype=np.float64).reshape(-1)
    if len(scores) != len(classes):
        raise ParameterError("scores", len(scores), f"one score per detection ({len(classes)} detections)")
    return boxes[on], scores[on]


def _ignored_boxes(item: dict, cls: int) -> np.ndarray:
    """The ignored boxes of class `cls` in a ground-truth entry (none when it names none)."""
    ignored = {"boxes": item.get("ignored_boxes", np.zeros((0, 4))), "classes": item.get("ignored_classes", [])}
    return _class_arrays(ignored, cls, need_scores=False)[0]


def precision_recall(detections: list[dict], ground_truth: list[dict], cls: int, iou_threshold: float = 0.5,
                     max_detections: int | None = None) -> tuple[np.ndarray, np.ndarray, int]:
    """(recall, precision) at every rank of class `cls`'s detections over the data set, and the
    number of ground-truth boxes; max_detections keeps each image's best M of this class (COCO's
    maxDets), before detections on ignored boxes are dropped."""
    scores_all, tp_all, n_gt = [], [], 0
    for det, gt in zip(detections, ground_truth):
        gt_boxes, _ = _class_arrays(gt, cls, need_scores=False)
        boxes, scores = _class_arrays(det, cls, need_scores=True)
        order = np.argsort(-scores, kind="mergesort")[:max_detections]
        tp, dropped = _match_image(boxes[order], gt_boxes, _ignored_boxes(gt, cls), iou_threshold)
        scores_all.append(scores[order][~dropped])
        tp_all.append(tp[~dropped])
        n_gt += len(gt_boxes)
    scores = np.concatenate(scores_all) if scores_all else np.zeros(0)
    tp = np.concatenate(tp_all) if tp_all else np.zeros(0, dtype=bool)
    tp = tp[np.argsort(-scores, kind="mergesort")]
    tp_sum = np.cumsum(tp, dtype=np.float64)
    fp_sum = np.cumsum(~tp, dtype=np.float64)
    recall = tp_sum / n_gt if n_gt else np.zeros_like(tp_sum)
    precision = tp_sum / np.maximum(tp_sum + fp_sum, 1.0)
    return recall, precision, n_gt


def _envelope(precision: np.ndarray) -> np.ndarray:
    """max_{j ≥ i} precision_j."""
    return np.maximum.accumulate(precision[::-1])[::-1]


def ap_voc_all_point(recall: np.ndarray, precision: np.ndarray) -> float:
    """VOC all-point AP: area under the precision envelope, summed over the recall steps."""
    if recall.size == 0:
        return 0.0
    steps = np.diff(np.concatenate([[0.0], recall]))
    return float(np.sum(steps * _envelope(precision)))


def ap_coco_101(recall: np.ndarray, precision: np.ndarray) -> float:
    """COCO AP: mean of the precision envelope at the 101 recalls 0…1 (0 past the highest recall)."""
    if recall.size == 0:
        return 0.0
    idx = np.searchsorted(recall, COCO_RECALLS, side="left")
    env = np.concatenate([_envelope(precision), [0.0]])
    return float(np.mean(env[np.minimum(idx, recall.size)]))


def evaluate_map(detections: list[dict], ground_truth: list[dict], class_names: list[str],
                 iou: float = 0.5, method: str = "voc", max_detections: int | None = None) -> MapResult:
    """AP per class and mAP over a data set (module docstring for the rules)."""
    if method not in METHODS:
        raise ParameterError("method", method, f"one of {', '.join(METHODS)}")
    if len(detections) != len(ground_truth):
        raise ParameterError("detections", len(detections), f"one entry per image ({len(ground_truth)} images)")
    if not 0.0 < iou < 1.0:
        raise ParameterError("iou", iou, "a threshold in (0, 1)")
    integrate = ap_voc_all_point if method == "voc" else ap_coco_101
    ap, n_gt, curves = {}, {}, {}
    for k, name in enumerate(class_names):
        recall, precision, n = precision_recall(detections, ground_truth, k, iou, max_detections)
        ap[name] = integrate(recall, precision) if n else math.nan
        n_gt[name], curves[name] = n, (recall, precision)
    with_gt = [v for v in ap.values() if not math.isnan(v)]
    notes = [f"no ground truth for {name}: left out of the mean" for name, v in ap.items() if math.isnan(v)]
    return MapResult(ap, float(np.mean(with_gt)) if with_gt else math.nan, n_gt, curves, method, iou, notes)


def pycocotools_ap50(detections: list[dict], ground_truth: list[dict], class_names: list[str],
                     max_detections: int = 100) -> dict:
    """AP@0.5 per class and their mean from pycocotools' COCOeval (area range 'all', maxDets
    max_detections) on the same data, ignored boxes as iscrowd = 1 (COCO's IoA rule for them, not
    this module's centre rule): {"ap": {name: AP or NaN}, "mean_ap": …}.

    When no image has any detection, pycocotools cannot load the empty result list; every class
    with ground truth then has AP 0, which is what COCOeval gives for a class without detections."""
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    images, annotations, results = [], [], []
    for i, (det, gt) in enumerate(zip(detections, ground_truth)):
        images.append({"id": i})
        for prefix, crowd in (("", 0), ("ignored_", 1)):
            for box, cls in zip(np.asarray(gt.get(prefix + "boxes", np.zeros((0, 4))), dtype=float).reshape(-1, 4),
                                np.asarray(gt.get(prefix + "classes", [])).reshape(-1)):
                w, h = box[2] - box[0], box[3] - box[1]
                annotations.append({"id": len(annotations) + 1, "image_id": i, "category_id": int(cls),
                                    "bbox": [box[0], box[1], w, h], "area": w * h, "iscrowd": crowd})
        for box, cls, score in zip(np.asarray(det["boxes"], dtype=float).reshape(-1, 4),
                                   np.asarray(det["classes"]).reshape(-1), np.asarray(det["scores"]).reshape(-1)):
            results.append({"image_id": i, "category_id": int(cls), "score": float(score),
                            "bbox": [box[0], box[1], box[2] - box[0], box[3] - box[1]]})
    has_gt = {int(a["category_id"]) for a in annotations if not a["iscrowd"]}
    ap = {name: (0.0 if k in has_gt else math.nan) for k, name in enumerate(class_names)}
    if results:
        with contextlib.redirect_stdout(io.StringIO()):
            coco_gt = COCO()
            coco_gt.dataset = {"images": images, "annotations": annotations,
                               "categories": [{"id": k, "name": n} for k, n in enumerate(class_names)]}
            coco_gt.createIndex()
            evaluator = COCOeval(coco_gt, coco_gt.loadRes(results), "bbox")
            evaluator.params.iouThrs = np.array([0.5])
            evaluator.params.maxDets = [1, 10, int(max_detections)]
            evaluator.evaluate()
            evaluator.accumulate()
        precision = evaluator.eval["precision"][0, :, :, 0, -1]      # recall × class, area 'all', last maxDets
        for k, name in enumerate(class_names):
            column = precision[:, evaluator.params.catIds.index(k)]
            ap[name] = float(column.mean()) if np.all(column > -1) else math.nan
    with_gt = [v for v in ap.values() if not math.isnan(v)]
    return {"ap": ap, "mean_ap": float(np.mean(with_gt)) if with_gt else math.nan}


BOOTSTRAP_SEED = 0x626F6F74            # 'boot': every run draws the same test-set resamples


def bootstrap_weights(n_images: int, resamples: int, seed: int = BOOTSTRAP_SEED) -> np.ndarray:
    """resamples × n_images multiplicities (int32) of test-set resamples drawn with replacement."""
    rng = np.random.default_rng([seed, n_images])
    return rng.multinomial(n_images, np.full(n_images, 1.0 / n_images), size=resamples).astype(np.int32)


@dataclass
class MatchTable:
    """Every detection of a test set that the ignore rule keeps, ranked by score per class, with its
    true-positive flag under the module's matching rule, and the ground-truth count of every image
    and class."""

    classes: np.ndarray          # D int: class of each detection
    images: np.ndarray           # D int: image of each detection
    tp: np.ndarray               # D bool
    order: list[np.ndarray]      # per class: indices into the arrays above, best score first
    n_gt: np.ndarray             # images × classes int

    def mean_ap(self, weights: np.ndarray, chunk: int = 128) -> np.ndarray:
        """VOC all-point mAP (over classes with ground truth in the resample) for each row of
        image multiplicities `weights` (R × images) → R float64 (NaN where no class has any)."""
        weights = np.atleast_2d(np.asarray(weights, dtype=np.float64))
        aps = np.full((weights.shape[0], self.n_gt.shape[1]), np.nan)
        for k, idx in enumerate(self.order):
            n_gt = weights @ self.n_gt[:, k]
            for lo in range(0, weights.shape[0], chunk):
                w = weights[lo:lo + chunk][:, self.images[idx]]
                tp_cum = np.cumsum(w * self.tp[idx], axis=1)
                fp_cum = np.cumsum(w * ~self.tp[idx], axis=1)
                n = n_gt[lo:lo + chunk, None]
                recall = tp_cum / np.where(n > 0, n, 1.0)
                precision = tp_cum / np.maximum(tp_cum + fp_cum, 1e-12)
                envelope = np.maximum.accumulate(precision[:, ::-1], axis=1)[:, ::-1]
                steps = np.diff(recall, axis=1, prepend=0.0)
                ap = (steps * envelope).sum(axis=1) if idx.size else np.zeros(len(n))
                aps[lo:lo + chunk, k] = np.where(n[:, 0] > 0, ap, np.nan)
        with np.errstate(invalid="ignore"):
            counted = ~np.isnan(aps)
            return np.where(counted.any(axis=1), np.nansum(aps, axis=1) / np.maximum(counted.sum(axis=1), 1), np.nan)


def match_table(detections: list[dict], ground_truth: list[dict], num_classes: int,
                iou: float = 0.5) -> MatchTable:
    """The MatchTable of a test set (same matching, dropping and ranking as evaluate_map)."""
    if len(detections) != len(ground_truth):
        raise ParameterError("detections", len(detections), f"one entry per image ({len(ground_truth)} images)")
    classes, images, tp, scores = [], [], [], []
    n_gt = np.zeros((len(ground_truth), num_classes), dtype=np.int64)
    for i, (det, gt) in enumerate(zip(detections, ground_truth)):
        for k in range(num_classes):
            gt_boxes, _ = _class_arrays(gt, k, need_scores=False)
            boxes, sc = _class_arrays(det, k, need_scores=True)
            n_gt[i, k] = len(gt_boxes)
            order = np.argsort(-sc, kind="mergesort")
            flags, dropped = _match_image(boxes[order], gt_boxes, _ignored_boxes(gt, k), iou)
            order = order[~dropped]
            tp.append(flags[~dropped])
            scores.append(sc[order])
            classes.append(np.full(len(order), k))
            images.append(np.full(len(order), i))
    cat = (lambda parts, dtype: np.concatenate(parts).astype(dtype) if parts else np.zeros(0, dtype))
    classes, images, tp, scores = cat(classes, np.int64), cat(images, np.int64), cat(tp, bool), cat(scores, np.float64)
    ranked = []
    for k in range(num_classes):
        idx = np.flatnonzero(classes == k)        # image order, then rank in the image …
        ranked.append(idx[np.argsort(-scores[idx], kind="mergesort")])      # … then score, stable
    return MatchTable(classes, images, tp, ranked, n_gt)

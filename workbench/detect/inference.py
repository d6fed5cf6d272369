"""Testing a detector on a data view: VOC AP@0.5 per class and mAP (ignored boxes handled by the
rule of workbench.detect.evaluate), pycocotools' AP@0.5 as a cross-check, and test-set bootstrap
resamples of the mAP for paired comparisons between runs."""
from __future__ import annotations

import math
import time

import numpy as np


def detect_view(model, view, *, device: str = "cpu", batch_size: int = 16, workers: int = 0,
                precision: str = "auto"):
    """(detections, truths, infer_s, sensor_isp_s) of a view, truths with their ignored boxes for
    evaluate's rule (inference under devices.autocast_dtype(device, precision), decoding in float32)."""
    import torch

    from workbench.detect.centernet import decode
    from workbench.detect.devices import autocast, autocast_dtype, prepare_input
    from workbench.detect.data import batches, iterate_batches

    detections, truths = [], []
    infer_s, sensor_isp_s = 0.0, 0.0
    amp_dtype = autocast_dtype(device, precision)
    with torch.no_grad():
        for x, targets in iterate_batches(view, batches(len(view), batch_size, None), workers):
            sensor_isp_s += sum(t["sensor_isp_s"] for t in targets)
            t0 = time.perf_counter()
            with autocast(device, amp_dtype):
                out = model(prepare_input(x, device))
            dets = decode({k: v.float() for k, v in out.items()}, stride=4, k=100, score_threshold=0.01)
            if device == "cuda":
                torch.cuda.synchronize()
            infer_s += time.perf_counter() - t0
            for det, tgt in zip(dets, targets):
                detections.append(det)
                truths.append({"boxes": tgt["boxes_xyxy"].numpy(), "classes": tgt["classes"].numpy(),
                               "ignored_boxes": tgt["ignored_xyxy"].numpy(),
                               "ignored_classes": tgt["ignored_classes"].numpy()})
    return detections, truths, infer_s, sensor_isp_s


def evaluate_detector(model, view, class_names, *, device: str = "cpu", batch_size: int = 16,
                      with_curves: bool = False, workers: int = 0, precision: str = "auto",
                      bootstrap: int = 0) -> dict:
    """mAP (None where no class has ground truth), AP per class and ground-truth counts, COCO
    AP@0.5 (ignored boxes as COCO crowd boxes; None without pycocotools), inference and sensor +
    ISP ms per image; with_curves: each class's precision–recall curve (≤ 50 points);
    bootstrap > 0: that many test-set resamples of the mAP ('bootstrap_map', float list;
    evaluate.bootstrap_weights, the same resamples for every run on this view)."""
    from workbench.detect.evaluate import bootstrap_weights, evaluate_map, match_table, pycocotools_ap50

    detections, truths, infer_s, sensor_isp_s = detect_view(model, view, device=device, batch_size=batch_size,
                                                            workers=workers, precision=precision)
    voc = evaluate_map(detections, truths, list(class_names), iou=0.5).to_dict()
    out = {"map": voc["mean_ap"], "ap": voc["ap"], "n_ground_truth": voc["n_ground_truth"],
           "images": len(view), "infer_ms_per_image": 1e3 * infer_s / max(len(view), 1),
           "sensor_isp_ms_per_image": 1e3 * sensor_isp_s / max(len(view), 1)}
    try:
        coco = pycocotools_ap50(detections, truths, list(class_names))["mean_ap"]
        out["coco_ap50"] = None if math.isnan(coco) else coco
    except ImportError:                      # pycocotools absent (a bare GPU machine): no cross-check
        out["coco_ap50"] = None
    if with_curves:
        out["curves"] = {name: {k: _thin(v) for k, v in curve.items()} for name, curve in voc["curves"].items()}
    if bootstrap:
        maps = match_table(detections, truths, len(class_names)).mean_ap(bootstrap_weights(len(truths), bootstrap))
        out["bootstrap_map"] = [None if math.isnan(v) else round(float(v), 6) for v in maps]
    return out


def _thin(values: list, points: int = 50) -> list:
    """At most `points` evenly spaced entries of a precision or recall list (keeps the last)."""
    if len(values) <= points:
        return values
    return [values[int(i)] for i in np.linspace(0, len(values) - 1, points).round()]

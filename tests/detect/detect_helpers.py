"""Shared helpers for the detector tests (imported by name: pytest puts this folder on sys.path)."""
from __future__ import annotations

import numpy as np
import torch


def perfect_outputs(targets: dict) -> dict:
    """The outputs a perfect network would give: logit of the target heat-map, size/offset at centres."""
    heat = targets["heatmap"].clamp(1e-6, 1 - 1e-6)
    b, _, h, w = heat.shape
    dense = {}
    for key in ("size", "offset"):
        maps = torch.zeros(b, 2, h * w)
        for i in range(b):
            on = targets["mask"][i] > 0
            maps[i][:, targets["index"][i][on]] = targets[key][i][on].T
        dense[key] = maps.reshape(b, 2, h, w)
    return {"heatmap": torch.log(heat / (1 - heat)), **dense}


def random_boxes(rng, n, image_hw, min_px=6):
    h, w = image_hw
    x1, y1 = rng.uniform(0, w - min_px, n), rng.uniform(0, h - min_px, n)
    x2 = np.minimum(w, x1 + rng.uniform(min_px, w / 2, n))
    y2 = np.minimum(h, y1 + rng.uniform(min_px, h / 2, n))
    return np.stack([x1, y1, x2, y2], axis=1)

"""Per-data-set label statistics: objects per frame and per class, box-height and distance
histograms, occlusion and truncation rates (numpy only; the chart draws with matplotlib's Agg).

Counted objects are the labelled ones (amodal mask reaches the image, labels.ObjectLabel);
"visible" ones have visible_px > 0. Box heights are the visible boxes' (px, visible objects
only); distances are labels' distance_m (every labelled object). A value beyond the last bin edge
is counted in the last bin. An empty data set gives zeros, never NaN.
"""
from __future__ import annotations

import io
from pathlib import Path
from typing import Sequence

import numpy as np

from workbench.files import atomic_write_bytes, atomic_write_text, json_text

STATS_NAME, PLOT_NAME = "statistics.json", "statistics.png"
BOX_HEIGHT_EDGES_PX = (0, 8, 16, 32, 64, 128, 256, 512, 1024)
DISTANCE_EDGES_M = (0, 5, 10, 15, 20, 30, 50, 75, 100, 150, 200)
# The road users a detector is trained on; "objects of interest per frame" counts these only.
CLASSES_OF_INTEREST = ("car", "pedestrian", "bus", "truck")


def _hist(values: np.ndarray, edges: Sequence[float]) -> list[int]:
    """Counts per bin [e_i, e_i+1); values beyond the last edge go to the last bin."""
    e = np.asarray(edges, dtype=np.float64)
    idx = np.clip(np.searchsorted(e, values, side="right") - 1, 0, e.size - 2)
    return np.bincount(idx, minlength=e.size - 1).astype(int).tolist()


def _ratio(num: float, den: float) -> float:
    return float(num) / float(den) if den else 0.0


def _rates(objs: list) -> dict:
    """Counts and occlusion/truncation rates of a list of ObjectLabel."""
    n = len(objs)
    occ = np.array([o.occlusion for o in objs], dtype=np.float64)
    trunc = np.array([o.truncation for o in objs], dtype=np.float64)
    return {
        "objects": n,
        "visible_objects": sum(o.visible_px > 0 for o in objs),
        "occluded_fraction": _ratio(np.count_nonzero(occ > 0), n),
        "fully_occluded_fraction": _ratio(sum(o.visible_px == 0 for o in objs), n),
        "mean_occlusion": _ratio(occ.sum(), n),
        "truncated_fraction": _ratio(sum(bool(o.truncated) for o in objs), n),
        "mean_truncation": _ratio(trunc.sum(), n),
    }


def _visible_per_frame(per_frame: list[list]) -> np.ndarray:
    return np.array([sum(o.visible_px > 0 for o in f) for f in per_frame], dtype=np.int64)


def dataset_statistics(frames: Sequence, classes_of_interest: Sequence[str] = CLASSES_OF_INTEREST) -> dict:
    """Statistics of a data set given each frame's labels.Labels (or any object with .objects);
    `objects_of_interest` repeats the per-frame counts and rates for `classes_of_interest` alone."""
    per_frame = [list(f.objects) for f in frames]
    interest = [[o for o in f if o.class_name in classes_of_interest] for f in per_frame]
    visible_interest = _visible_per_frame(interest)
    objs = [o for f in per_frame for o in f]
    visible_per_frame = _visible_per_frame(per_frame)
    heights_px = np.array([o.bbox_xywh[3] for o in objs if o.visible_px > 0], dtype=np.float64)
    dist_m = np.array([o.distance_m for o in objs], dtype=np.float64)
    classes = sorted({o.class_name for o in objs})
    return {
        "frames": len(per_frame),
        **_rates(objs),
        "objects_per_frame_mean": _ratio(len(objs), len(per_frame)),
        "visible_objects_per_frame_mean": _ratio(visible_per_frame.sum(), len(per_frame)),
        "visible_objects_per_frame_histogram": np.bincount(visible_per_frame).astype(int).tolist(),
        "per_class": {c: _rates([o for o in objs if o.class_name == c]) for c in classes},
        "objects_of_interest": {
            "classes": list(classes_of_interest), **_rates([o for f in interest for o in f]),
            "visible_per_frame_mean": _ratio(visible_interest.sum(), len(per_frame)),
            "visible_per_frame_histogram": np.bincount(visible_interest).astype(int).tolist()},
        "box_height_px": {"edges": list(BOX_HEIGHT_EDGES_PX), "counts": _hist(heights_px, BOX_HEIGHT_EDGES_PX),
                          "median": float(np.median(heights_px)) if heights_px.size else 0.0},
        "distance_m": {"edges": list(DISTANCE_EDGES_M), "counts": _hist(dist_m, DISTANCE_EDGES_M),
                       "median": float(np.median(dist_m)) if dist_m.size else 0.0},
    }


def draw_statistics(stats: dict, fig) -> None:
    """Draw objects per frame, objects per class and the two histograms on a matplotlib Figure."""
    ax1, ax2, ax3, ax4 = fig.subplots(1, 4)
    from matplotlib.ticker import MaxNLocator
    interest = stats["objects_of_interest"]
    counts = interest["visible_per_frame_histogram"]
    ax1.bar(range(len(counts)), counts)
    ax1.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax1.set(xlabel=f"visible {'/'.join(interest['classes'])} in a frame", ylabel="frames",
            title=f"{stats['frames']} frames, mean {interest['visible_per_frame_mean']:.2f}")
    names = list(stats["per_class"])
    ax2.barh(names, [stats["per_class"][c]["visible_objects"] for c in names], label="visible")
    ax2.barh(names, [stats["per_class"][c]["objects"] - stats["per_class"][c]["visible_objects"] for c in names],
             left=[stats["per_class"][c]["visible_objects"] for c in names], label="fully occluded")
    ax2.set(xlabel="objects", title=f"occluded {100 * stats['occluded_fraction']:.0f} %, "
                                    f"truncated {100 * stats['truncated_fraction']:.0f} %")
    ax2.legend(fontsize="small")
    for ax, key, label, unit in ((ax3, "box_height_px", "visible box height (px)", "px"),
                                 (ax4, "distance_m", "distance (m)", "m")):
        h = stats[key]
        edges = h["edges"]
        ticks = [f"{a:g}–{b:g}" for a, b in zip(edges[:-2], edges[1:-1])] + [f"≥ {edges[-2]:g}"]
        ax.bar(range(len(h["counts"])), h["counts"], width=0.9)
        ax.set_xticks(range(len(h["counts"])), ticks, rotation=60, fontsize="small")
        ax.set(xlabel=label, ylabel="objects", title=f"median {h['median']:.1f} {unit}")


def write_statistics(out_dir: str | Path, frames: Sequence) -> tuple[Path, Path]:
    """Write statistics.json and statistics.png (atomically) into out_dir; returns both paths."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    out = Path(out_dir)
    stats = dataset_statistics(frames)
    json_path = atomic_write_text(out / STATS_NAME, json_text(stats) + "\n")
    fig = Figure(figsize=(18, 4.5), layout="constrained")
    FigureCanvasAgg(fig)
    draw_statistics(stats, fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    png_path = atomic_write_bytes(out / PLOT_NAME, buf.getvalue())
    return json_path, png_path

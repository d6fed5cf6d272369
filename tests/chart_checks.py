"""Checks that a matplotlib figure is readable as drawn: titles inside the figure and clear of each
other, legends inside the figure and clear of every data point shown in any axes."""
from __future__ import annotations

import itertools

import numpy as np


def _inside(box, points: np.ndarray) -> np.ndarray:
    return ((points[:, 0] > box.x0) & (points[:, 0] < box.x1) & (points[:, 1] > box.y0) & (points[:, 1] < box.y1))


def shown_points(ax) -> np.ndarray:
    """Display coordinates (px) of the data an axes shows: its lines' vertices and bars' corners
    inside the axes (what the axes clips away is not seen)."""
    pts = []
    for line in ax.lines:
        xy = np.column_stack([np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)])
        pts.append(line.get_transform().transform(xy[np.all(np.isfinite(xy), axis=1)]))
    for patch in ax.patches:
        box = patch.get_window_extent()
        pts.append(np.array([[box.x0, box.y1], [box.x1, box.y1], [0.5 * (box.x0 + box.x1), box.y1]]))
    pts = np.concatenate([p for p in pts if len(p)]) if pts else np.zeros((0, 2))
    return pts[_inside(ax.get_window_extent(), pts)] if len(pts) else pts


def assert_readable(fig) -> None:
    """fig has been drawn (fig.canvas.draw()). Titles (of every axes) lie inside the figure and do not
    overlap one another or a legend; legends lie inside the figure and cover no shown data point."""
    renderer = fig.canvas.get_renderer()
    page = fig.bbox
    titles = [(ax.get_title(), ax.title.get_window_extent(renderer)) for ax in fig.axes if ax.get_title()]
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    legend_boxes = [leg.get_window_extent(renderer) for leg in legends]
    for text, box in titles + [("legend", b) for b in legend_boxes]:
        assert box.x0 >= page.x0 - 1 and box.x1 <= page.x1 + 1 and box.y0 >= page.y0 - 1 and box.y1 <= page.y1 + 1, \
            f"'{text}' {box.bounds} is cut by the figure's edge {page.bounds}"
    for (ta, a), (tb, b) in itertools.combinations(titles, 2):
        assert not a.overlaps(b), f"titles '{ta}' and '{tb}' overlap"
    for (text, title), legend in itertools.product(titles, legend_boxes):
        assert not title.overlaps(legend), f"a legend covers the title '{text}'"
    for legend, ax in itertools.product(legend_boxes, fig.axes):
        covered = _inside(legend, shown_points(ax))
        assert not covered.any(), f"a legend covers {int(covered.sum())} data points of '{ax.get_title()}'"

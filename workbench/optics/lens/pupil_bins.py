"""Exit-pupil boxes per radial bin of the film, for a camera that samples the pupil per film point.

PBRT's realistic camera: for film points in each radial bin, the box on the rear-vertex plane
through which light from the scene can reach them (found by tracing in numpy, cached per lens,
film radius and bin count). The Mitsuba lens camera (workbench.render.lens_camera) samples these
boxes; nothing here needs Mitsuba.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from workbench.optics.lens.analysis import _rear_rays, rear_pupil_box
from workbench.optics.lens.glass import LINE_D_NM
from workbench.optics.lens.model import Lens
from workbench.optics.lens.trace import trace_rays

N_BINS = 32
BOX_CACHE_SIZE = 32       # prepared lenses (a focus edit makes a new one): the cache stays bounded

ELLIPSE_MARGIN = 0.98   # a bin samples its box's inscribed ellipse when no light passes outside 0.98 of it


def _ellipse_holds_pupil(lens: Lens, heights_mm, box, wavelength_nm: float, n_side: int = 64) -> bool:
    """True when no ray from the film points at `heights_mm` (on +y) that passes the whole lens
    crosses the rear-vertex plane outside ELLIPSE_MARGIN × the ellipse inscribed in `box`
    (checked on an n_side² grid over the box), so sampling the ellipse loses no light."""
    x0, x1, y0, y1 = box
    g = (np.arange(n_side) + 0.5) / n_side * 2.0 - 1.0
    u, v = (a.ravel() for a in np.meshgrid(g, g))
    out = u * u + v * v > ELLIPSE_MARGIN ** 2
    xy = np.column_stack([(x0 + x1) / 2 + u[out] * (x1 - x0) / 2, (y0 + y1) / 2 + v[out] * (y1 - y0) / 2])
    for h in heights_mm:
        p, d, _ = _rear_rays(lens, float(h), xy)
        if trace_rays(lens, p, d, wavelength_nm, reverse=True).valid.any():
            return False
    return True


def pupil_bins(lens: Lens, max_radius_mm: float, n_bins: int = N_BINS,
               wavelength_nm: float = LINE_D_NM) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exit-pupil boxes per radial bin of the film: (edges (n+1,), boxes (n, 4) as x0, x1, y0, y1
    on the rear-vertex plane for film points on +y, an all-zero box where no ray passes; ellipse
    (n,) bool: the bin may sample the box's inscribed ellipse instead (π/4 of the area, so fewer
    rays die; checked at the bin's edges and centre). Cached (the BOX_CACHE_SIZE latest)."""
    return _pupil_bins(lens, round(float(max_radius_mm), 9), int(n_bins), float(wavelength_nm))


@lru_cache(maxsize=BOX_CACHE_SIZE)
def _pupil_bins(lens: Lens, max_radius_mm: float, n_bins: int, wavelength_nm: float):
    edges = np.linspace(0.0, max_radius_mm * 1.0001, n_bins + 1)
    at = [rear_pupil_box(lens, float(h), wavelength_nm) for h in edges]
    boxes = np.zeros((n_bins, 4))
    ellipse = np.zeros(n_bins, dtype=bool)
    for i in range(n_bins):
        have = [b for b in (at[i], at[i + 1]) if b is not None]
        if have:
            boxes[i] = (min(b[0] for b in have), max(b[1] for b in have),
                        min(b[2] for b in have), max(b[3] for b in have))
            ellipse[i] = _ellipse_holds_pupil(lens, (edges[i], (edges[i] + edges[i + 1]) / 2, edges[i + 1]),
                                              boxes[i], wavelength_nm)
    for a in (edges, boxes, ellipse):
        a.flags.writeable = False          # shared by every caller
    return edges, boxes, ellipse

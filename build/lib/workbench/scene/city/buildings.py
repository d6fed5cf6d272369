"""Buildings: lots split into parcels, each with a box, L-shaped or podium-and-tower building,
a facade material and a grid of windows (glass quads 2 cm proud of the facade).

Storey heights follow common practice: 4.0 m ground floor, 3.2 m upper floors; windows
1.4 m × 1.6 m on a 2.8 m bay with a 0.9 m sill.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.scene.city import geometry as g
from workbench.scene.city.materials import FACADES

MIN_PARCEL_M = 14.0
GROUND_FLOOR_M, FLOOR_M = 4.0, 3.2
BAY_M, WINDOW_W_M, WINDOW_H_M, SILL_M = 2.8, 1.4, 1.6, 0.9
WINDOW_PROUD_M = 0.02


@dataclass(frozen=True)
class BuildingPlan:
    """One building: axis-aligned parts (lo xyz, hi xyz in m) and its facade material."""

    parts: tuple[tuple[tuple[float, float, float], tuple[float, float, float]], ...]
    facade: str
    style: str          # 'box' | 'L' | 'tower'

    @property
    def height_m(self) -> float:
        return max(hi[2] for _, hi in self.parts)


def split_lot(lot: tuple[float, float, float, float], rng: np.random.Generator) -> list[tuple]:
    """Guillotine-split a lot into parcels no smaller than MIN_PARCEL_M on a side."""
    out, todo = [], [(tuple(lot), 0)]
    while todo:
        (x0, y0, x1, y1), depth = todo.pop()
        w, h = x1 - x0, y1 - y0
        longest = max(w, h)
        if longest < 2 * MIN_PARCEL_M or (depth >= 2 and rng.random() < 0.3) or depth >= 5:
            out.append((x0, y0, x1, y1))
            continue
        t = rng.uniform(0.35, 0.65)
        if w >= h:
            xm = float(np.clip(x0 + t * w, x0 + MIN_PARCEL_M, x1 - MIN_PARCEL_M))
            todo += [((x0, y0, xm, y1), depth + 1), ((xm, y0, x1, y1), depth + 1)]
        else:
            ym = float(np.clip(y0 + t * h, y0 + MIN_PARCEL_M, y1 - MIN_PARCEL_M))
            todo += [((x0, y0, x1, ym), depth + 1), ((x0, ym, x1, y1), depth + 1)]
    return sorted(out)


def plan_building(parcel: tuple, z0_m: float, h_min_m: float, h_max_m: float,
                  rng: np.random.Generator) -> BuildingPlan:
    """A building on a parcel: 1–4 m set back from each parcel edge, height in [h_min, h_max]."""
    x0, y0, x1, y1 = parcel
    m = rng.uniform(1.0, 4.0, size=4)
    x0, y0, x1, y1 = x0 + m[0], y0 + m[1], x1 - m[2], y1 - m[3]
    h = float(rng.uniform(h_min_m, h_max_m))
    facade = FACADES[int(rng.integers(len(FACADES)))]
    style = ("box", "L", "tower")[int(rng.choice(3, p=[0.5, 0.25, 0.25]))]
    w, d = x1 - x0, y1 - y0
    if style == "L" and min(w, d) > 10:
        fx, fy = rng.uniform(0.4, 0.6, size=2)
        cx, cy = (x0 + fx * w, y0 + fy * d)
        flip_x, flip_y = rng.random() < 0.5, rng.random() < 0.5
        ya, yb = (cy, y1) if flip_y else (y0, cy)
        xa, xb = (x0, cx) if flip_x else (cx, x1)
        h2 = float(rng.uniform(max(h_min_m, 0.6 * h), h))
        parts = (((x0, ya, z0_m), (x1, yb, z0_m + h)), ((xa, y0, z0_m), (xb, y1, z0_m + h2)))
    elif style == "tower" and min(w, d) > 12 and h > 2 * GROUND_FLOOR_M + FLOOR_M:
        podium = GROUND_FLOOR_M + FLOOR_M * int(rng.integers(0, 2))
        inset = rng.uniform(0.15, 0.3, size=2) * np.array([w, d])
        parts = (((x0, y0, z0_m), (x1, y1, z0_m + podium)),
                 ((x0 + inset[0], y0 + inset[1], z0_m), (x1 - inset[0], y1 - inset[1], z0_m + h)))
    else:
        style = "box"
        parts = (((x0, y0, z0_m), (x1, y1, z0_m + h)),)
    return BuildingPlan(parts, facade, style)


def building_parts(plan: BuildingPlan) -> dict[str, g.Part]:
    """Facade boxes and window quads of a building plan, by material."""
    lo = np.array([p[0] for p in plan.parts])
    hi = np.array([p[1] for p in plan.parts])
    walls = g.boxes(lo, hi)
    windows = [_windows(np.array(a), np.array(b)) for a, b in plan.parts]
    return {plan.facade: walls, "glass_dark": g.merge([w for w in windows if len(w[1])])}


def _windows(lo: np.ndarray, hi: np.ndarray) -> g.Part:
    """Window quads on the four facades of one box part."""
    n = int((hi[2] - lo[2]) // FLOOR_M) + 1
    z_sill = lo[2] + SILL_M + np.concatenate(([0.0], GROUND_FLOOR_M + FLOOR_M * np.arange(n)))
    z_sill = z_sill[z_sill + WINDOW_H_M < hi[2] - 0.4]
    if len(z_sill) == 0:
        return g.merge([])
    quads = []
    # facades: (axis along which the wall runs, fixed coordinate, outward sign)
    for axis, fixed, sign in ((0, lo[1], -1), (0, hi[1], 1), (1, lo[0], -1), (1, hi[0], 1)):
        a0, a1 = lo[axis], hi[axis]
        n_bay = int((a1 - a0) // BAY_M)
        if n_bay < 1:
            continue
        start = a0 + (a1 - a0 - n_bay * BAY_M) / 2 + (BAY_M - WINDOW_W_M) / 2
        u0 = start + BAY_M * np.arange(n_bay)
        U0, Z0 = np.meshgrid(u0, z_sill, indexing="ij")
        U0, Z0 = U0.ravel(), Z0.ravel()
        U1, Z1 = U0 + WINDOW_W_M, Z0 + WINDOW_H_M
        f = np.full_like(U0, fixed + sign * WINDOW_PROUD_M)
        if axis == 0:          # wall along x at y = fixed; outward ±y
            c = [(U0, f, Z0), (U1, f, Z0), (U1, f, Z1), (U0, f, Z1)]
            if sign > 0:
                c = [(U1, f, Z0), (U0, f, Z0), (U0, f, Z1), (U1, f, Z1)]
        else:                  # wall along y at x = fixed; outward ±x
            c = [(f, U1, Z0), (f, U0, Z0), (f, U0, Z1), (f, U1, Z1)]
            if sign > 0:
                c = [(f, U0, Z0), (f, U1, Z0), (f, U1, Z1), (f, U0, Z1)]
        quads.append(np.stack([np.stack(p, -1) for p in c], 1))
    if not quads:
        return g.merge([])
    return g.quads(np.concatenate(quads))

"""Street grid of a city recipe: streets, lanes, intersections, blocks, sidewalk rings, lots.

Street centre lines lie at multiples of the pitch (block_size_m + street width) on both axes,
so block (i, j) spans [i·pitch + s/2, (i+1)·pitch − s/2] with s the carriageway width. Traffic
keeps to the right: on a street along +Y the northbound lanes lie east of the centre line.
Rectangles are (xmin, ymin, xmax, ymax) in metres.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.scene.city.recipe import CityRecipe

CROSSWALK_LENGTH_M = 3.0     # zebra bars along the traffic direction (US/EU practice: 2.5–4 m)
CROSSWALK_OFFSET_M = 0.5     # gap between the intersection edge and the crosswalk
LANE_END_CLEARANCE_M = 5.0   # vehicles and cameras keep this far from a segment's ends


@dataclass(frozen=True)
class Lane:
    """One lane of one street segment (between two intersections), in its travel direction."""

    index: int
    start_xy: tuple[float, float]     # centre line at the segment's start (m)
    end_xy: tuple[float, float]
    heading_deg: float                # travel direction about +Z from +X: 0, 90, 180 or 270
    width_m: float
    segment_rect: tuple[float, float, float, float]   # the carriageway of this segment
    rank: int                         # 0 next to the centre line … lanes_per_direction−1 at the kerb

    @property
    def length_m(self) -> float:
        return float(np.hypot(self.end_xy[0] - self.start_xy[0], self.end_xy[1] - self.start_xy[1]))

    def point(self, s_m: float, offset_m: float = 0.0) -> np.ndarray:
        """Point at distance s_m along the lane, offset_m to the left of its centre line."""
        h = np.radians(self.heading_deg)
        d, left = np.array([np.cos(h), np.sin(h)]), np.array([-np.sin(h), np.cos(h)])
        return np.asarray(self.start_xy) + s_m * d + offset_m * left

    def lane_coords(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(distance along, offset left of the centre line) of points xy (N×2)."""
        h = np.radians(self.heading_deg)
        rel = np.atleast_2d(xy) - np.asarray(self.start_xy)
        return rel @ np.array([np.cos(h), np.sin(h)]), rel @ np.array([-np.sin(h), np.cos(h)])


@dataclass(frozen=True)
class CityLayout:
    """Where roads, sidewalks and building lots are."""

    street_width_m: float
    sidewalk_width_m: float
    curb_height_m: float
    road_bounds: tuple[float, float, float, float]   # outer kerbs of the outer streets
    road_rects: np.ndarray          # N×4, non-overlapping pieces of carriageway
    intersections: np.ndarray       # K×4
    blocks: np.ndarray              # B×4, kerb to kerb (sidewalks included)
    sidewalk_rects: np.ndarray      # 4B×4 (four strips per block: south, north, west, east)
    lots: np.ndarray                # B×4, block minus its sidewalk ring
    lanes: tuple[Lane, ...]

    def on_road(self, xy: np.ndarray) -> np.ndarray:
        """True for points (N×2) on the carriageway (inside the road bounds, outside every block)."""
        p = np.atleast_2d(xy)
        x0, y0, x1, y1 = self.road_bounds
        inside = (p[:, 0] >= x0) & (p[:, 0] <= x1) & (p[:, 1] >= y0) & (p[:, 1] <= y1)
        return inside & ~_in_any(p, self.blocks, 0.0)

    def on_sidewalk(self, xy: np.ndarray, tolerance_m: float = 0.0) -> np.ndarray:
        """True for points (N×2) within tolerance_m of a sidewalk strip."""
        return _in_any(np.atleast_2d(xy), self.sidewalk_rects, tolerance_m)


def _in_any(p: np.ndarray, rects: np.ndarray, tol: float) -> np.ndarray:
    r = rects[None]
    x, y = p[:, 0:1], p[:, 1:2]
    return np.any((x >= r[..., 0] - tol) & (x <= r[..., 2] + tol) &
                  (y >= r[..., 1] - tol) & (y <= r[..., 3] + tol), axis=1)


def build_layout(recipe: CityRecipe) -> CityLayout:
    """The street grid of a recipe (no randomness)."""
    s, p, sw = recipe.street_width_m, recipe.pitch_m, recipe.sidewalk_width_m
    nx, ny = recipe.blocks_x, recipe.blocks_y
    xc, yc = p * np.arange(nx + 1), p * np.arange(ny + 1)
    bounds = (-s / 2, -s / 2, nx * p + s / 2, ny * p + s / 2)
    road = [(x - s / 2, bounds[1], x + s / 2, bounds[3]) for x in xc]
    road += [(xc[i] + s / 2, y - s / 2, xc[i + 1] - s / 2, y + s / 2) for y in yc for i in range(nx)]
    inter = [(x - s / 2, y - s / 2, x + s / 2, y + s / 2) for x in xc for y in yc]
    blocks = [(xc[i] + s / 2, yc[j] + s / 2, xc[i + 1] - s / 2, yc[j + 1] - s / 2)
              for j in range(ny) for i in range(nx)]
    walks, lots = [], []
    for x0, y0, x1, y1 in blocks:
        walks += [(x0, y0, x1, y0 + sw), (x0, y1 - sw, x1, y1),
                  (x0, y0 + sw, x0 + sw, y1 - sw), (x1 - sw, y0 + sw, x1, y1 - sw)]
        lots.append((x0 + sw, y0 + sw, x1 - sw, y1 - sw))
    lanes = []
    lw, k_dir = recipe.lane_width_m, recipe.lanes_per_direction
    for x in xc:                          # streets along Y
        for j in range(ny):
            ya, yb = yc[j] + s / 2, yc[j + 1] - s / 2
            seg = (x - s / 2, ya, x + s / 2, yb)
            for k in range(k_dir):
                off = (k + 0.5) * lw
                lanes.append(((x + off, ya), (x + off, yb), 90.0, seg, k))
                lanes.append(((x - off, yb), (x - off, ya), 270.0, seg, k))
    for y in yc:                          # streets along X
        for i in range(nx):
            xa, xb = xc[i] + s / 2, xc[i + 1] - s / 2
            seg = (xa, y - s / 2, xb, y + s / 2)
            for k in range(k_dir):
                off = (k + 0.5) * lw
                lanes.append(((xb, y + off), (xa, y + off), 180.0, seg, k))
                lanes.append(((xa, y - off), (xb, y - off), 0.0, seg, k))
    lane_objs = tuple(Lane(i, tuple(map(float, a)), tuple(map(float, b)), h, lw,
                           tuple(map(float, seg)), k) for i, (a, b, h, seg, k) in enumerate(lanes))
    f = lambda rows: np.asarray(rows, dtype=np.float64).reshape(-1, 4)
    return CityLayout(s, sw, recipe.curb_height_m, tuple(map(float, bounds)), f(road), f(inter),
                      f(blocks), f(walks), f(lots), lane_objs)


def marking_rects(layout: CityLayout, lanes_per_direction: int
                  ) -> list[tuple[tuple[float, float, float, float], np.ndarray, np.ndarray]]:
    """Lane markings of every street segment: [(segment_rect, white N×4, yellow M×4), …].

    Double yellow centre line (2 × 0.12 m, 0.12 m apart), white dashed lane lines (3 m dash,
    9 m gap, 0.12 m wide — the US MUTCD 10 ft / 30 ft pattern) between same-direction lanes, and
    zebra crosswalks (0.5 m bars, 0.6 m apart) at both ends of every segment."""
    lw = layout.street_width_m / (2 * lanes_per_direction)
    out = []
    for x0, y0, x1, y1 in sorted({ln.segment_rect for ln in layout.lanes}):
        along_y = (y1 - y0) > (x1 - x0)
        a0, a1 = (y0, y1) if along_y else (x0, x1)          # along the street
        c = (x0 + x1) / 2 if along_y else (y0 + y1) / 2     # centre line (across coordinate)
        zebra_end = CROSSWALK_OFFSET_M + CROSSWALK_LENGTH_M
        line0, line1 = a0 + zebra_end + 1.0, a1 - zebra_end - 1.0
        white, yellow = [], []                              # rows (along0, along1, across0, across1)
        if line1 > line0:
            yellow += [(line0, line1, c + off, c + off + 0.12) for off in (-0.18, 0.06)]
            for k in range(1, lanes_per_direction):
                for sgn in (-1, 1):
                    cc = c + sgn * k * lw
                    white += [(a, a + 3.0, cc - 0.06, cc + 0.06)
                              for a in np.arange(line0, line1 - 3.0, 12.0)]
        half = layout.street_width_m / 2 - 0.3
        bars = np.arange(c - half, c + half - 0.5 + 1e-9, 1.1)
        for z0 in (a0 + CROSSWALK_OFFSET_M, a1 - zebra_end):
            white += [(z0, z0 + CROSSWALK_LENGTH_M, b, b + 0.5) for b in bars]
        out.append(((x0, y0, x1, y1), _to_xy(white, along_y), _to_xy(yellow, along_y)))
    return out


def _to_xy(rows: list, along_y: bool) -> np.ndarray:
    """(along0, along1, across0, across1) rows → (xmin, ymin, xmax, ymax)."""
    r = np.asarray(rows, dtype=np.float64).reshape(-1, 4)
    return r[:, [2, 0, 3, 1]] if along_y else r[:, [0, 2, 1, 3]]

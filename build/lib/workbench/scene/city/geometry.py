"""Triangle-mesh primitives (outward-facing, counter-clockwise seen from outside) and the 2-D
oriented-rectangle overlap test used by placement.

A part is a (vertices V×3 float64, faces F×3 int32) pair; `Part` lists are merged per material.
Winding matters: Mitsuba's diffuse BSDF is one-sided, so a face seen from behind renders black.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull

Part = tuple[np.ndarray, np.ndarray]


def convex_solid(points: np.ndarray) -> Part:
    """Closed triangle mesh of the convex hull of `points` (N×3, m), faces wound outward."""
    pts = np.asarray(points, dtype=np.float64)
    hull = ConvexHull(pts)
    faces = hull.simplices.astype(np.int64)
    a, b, c = pts[faces[:, 0]], pts[faces[:, 1]], pts[faces[:, 2]]
    normal = np.cross(b - a, c - a)
    flip = np.einsum("ij,ij->i", normal, hull.equations[:, :3]) < 0
    faces[flip] = faces[flip][:, [0, 2, 1]]
    used, inverse = np.unique(faces, return_inverse=True)
    return pts[used].copy(), inverse.reshape(-1, 3).astype(np.int32)


def box(lo: tuple[float, float, float], hi: tuple[float, float, float]) -> Part:
    """Axis-aligned box between corners lo and hi (m)."""
    return boxes(np.asarray([lo], float), np.asarray([hi], float))


_BOX_CORNERS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                         [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=np.float64)
_BOX_FACES = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                       [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]],
                      dtype=np.int32)


def boxes(lo: np.ndarray, hi: np.ndarray) -> Part:
    """Many axis-aligned boxes at once: lo, hi are N×3 corner arrays (m)."""
    lo, hi = np.atleast_2d(lo).astype(np.float64), np.atleast_2d(hi).astype(np.float64)
    verts = lo[:, None, :] + _BOX_CORNERS[None] * (hi - lo)[:, None, :]
    faces = _BOX_FACES[None] + 8 * np.arange(len(lo), dtype=np.int32)[:, None, None]
    return verts.reshape(-1, 3), faces.reshape(-1, 3)


def quads(corners: np.ndarray) -> Part:
    """Flat quads from N×4×3 corners given counter-clockwise as seen from the side they face."""
    c = np.asarray(corners, dtype=np.float64).reshape(-1, 4, 3)
    faces = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32)[None] + \
        4 * np.arange(len(c), dtype=np.int32)[:, None, None]
    return c.reshape(-1, 3), faces.reshape(-1, 3)


def ground_rects(rects_xy: np.ndarray, z_m: float) -> Part:
    """Upward-facing horizontal rectangles (N×4: xmin, ymin, xmax, ymax) at height z_m."""
    r = np.atleast_2d(np.asarray(rects_xy, dtype=np.float64))
    z = np.full(len(r), float(z_m))
    corners = np.stack([np.stack([r[:, 0], r[:, 1], z], -1), np.stack([r[:, 2], r[:, 1], z], -1),
                        np.stack([r[:, 2], r[:, 3], z], -1), np.stack([r[:, 0], r[:, 3], z], -1)], 1)
    return quads(corners)


def ring(radius_x: float, radius_y: float, z: float, n: int = 12,
         center_xy: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """n points of a horizontal ellipse (n×3) — building block for frustums and limbs."""
    t = 2 * np.pi * np.arange(n) / n
    return np.stack([center_xy[0] + radius_x * np.cos(t), center_xy[1] + radius_y * np.sin(t),
                     np.full(n, float(z))], axis=-1)


def cylinder_y(radius: float, y0: float, y1: float, center_xz: tuple[float, float],
               n: int = 14) -> Part:
    """Closed cylinder with its axis along Y (wheels); a vertex sits at the bottom (touches ground)."""
    t = 2 * np.pi * np.arange(n) / n - np.pi / 2
    x, z = center_xz[0] + radius * np.cos(t), center_xz[1] + radius * np.sin(t)
    pts = np.concatenate([np.stack([x, np.full(n, y0), z], -1), np.stack([x, np.full(n, y1), z], -1)])
    return convex_solid(pts)


def frustum(z0: float, z1: float, r0: tuple[float, float], r1: tuple[float, float],
            center_xy: tuple[float, float] = (0.0, 0.0), n: int = 10) -> Part:
    """Closed elliptic frustum between heights z0 and z1 (radii (rx, ry) at each end)."""
    return convex_solid(np.concatenate([ring(*r0, z0, n, center_xy), ring(*r1, z1, n, center_xy)]))


def ellipsoid(center: tuple[float, float, float], radii: tuple[float, float, float],
              n_lat: int = 6, n_lon: int = 10) -> Part:
    """Closed low-poly ellipsoid."""
    lat = np.pi * (np.arange(1, n_lat) / n_lat - 0.5)
    lon = 2 * np.pi * np.arange(n_lon) / n_lon
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    pts = np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], -1).reshape(-1, 3)
    pts = np.concatenate([pts, [[0, 0, -1], [0, 0, 1]]])
    return convex_solid(np.asarray(center) + pts * np.asarray(radii))


def extrude_xz(profile_xz: np.ndarray, y0: float, y1: float) -> Part:
    """Convex side profile (K×2 points in x, z) extruded from y0 to y1 (car and bus bodies)."""
    p = np.asarray(profile_xz, dtype=np.float64)
    k = len(p)
    pts = np.concatenate([np.stack([p[:, 0], np.full(k, y0), p[:, 1]], -1),
                          np.stack([p[:, 0], np.full(k, y1), p[:, 1]], -1)])
    return convex_solid(pts)


def merge(parts: list[Part]) -> Part:
    """Concatenate parts into one vertex/face array pair."""
    if not parts:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32)
    offsets = np.cumsum([0] + [len(v) for v, _ in parts[:-1]])
    verts = np.concatenate([v for v, _ in parts])
    faces = np.concatenate([f + o for (_, f), o in zip(parts, offsets)]).astype(np.int32)
    return verts, faces


def place(vertices: np.ndarray, heading_deg: float, position_m: np.ndarray) -> np.ndarray:
    """Rotate local vertices (x forward, y left, z up) about +Z by heading_deg, then translate."""
    h = np.radians(heading_deg)
    c, s = np.cos(h), np.sin(h)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return vertices @ rot.T + np.asarray(position_m, dtype=np.float64)


def oriented_rect(center_xy: np.ndarray, length_m: float, width_m: float,
                  heading_deg: float) -> np.ndarray:
    """Corners (4×2, counter-clockwise) of a rectangle of length along heading_deg and width across."""
    h = np.radians(heading_deg)
    u = np.array([np.cos(h), np.sin(h)]) * (length_m / 2)
    v = np.array([-np.sin(h), np.cos(h)]) * (width_m / 2)
    c = np.asarray(center_xy, dtype=np.float64)
    return np.array([c - u - v, c + u - v, c + u + v, c - u + v])


def _axes(rect: np.ndarray) -> np.ndarray:
    edges = np.roll(rect, -1, axis=0)[:2] - rect[:2]
    return np.stack([-edges[:, 1], edges[:, 0]], -1)


def rects_overlap(a: np.ndarray, b: np.ndarray, margin_m: float = 0.0) -> bool:
    """Separating-axis test of two oriented rectangles (4×2 corners each).

    True when they overlap or come closer than margin_m along every rectangle edge normal
    (the four candidate separating axes of two rectangles)."""
    for axis in np.concatenate([_axes(a), _axes(b)]):
        n = axis / np.linalg.norm(axis)
        pa, pb = a @ n, b @ n
        if pa.max() + margin_m <= pb.min() or pb.max() + margin_m <= pa.min():
            return False
    return True


def rect_inside(inner: np.ndarray, box_xy: tuple[float, float, float, float]) -> bool:
    """All corners of `inner` (K×2) inside the axis-aligned box (xmin, ymin, xmax, ymax)."""
    x0, y0, x1, y1 = box_xy
    return bool(np.all((inner[:, 0] >= x0) & (inner[:, 0] <= x1) &
                       (inner[:, 1] >= y0) & (inner[:, 1] <= y1)))

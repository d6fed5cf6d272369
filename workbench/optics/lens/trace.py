"""Real-ray tracing through a sequential lens, in float64, one compiled loop per ray (numba).

Intersection is vertex-relative: for the conic c(x² + y² + (1+k) z²) − 2z = 0 the ray p + t·d gives
A t² + 2b t + C = 0 with the stable roots q = −(b + sign(b)√(b² − AC)), t = C/q and q/A — exact for a
flat surface (A = 0) and free of cancellation for nearly flat ones. The root kept is the nearest one
ahead of the ray on the vertex branch ((1+k) c z ≤ 1). Even aspheres are refined by Newton's method
from the conic hit. Misses, total internal reflection and clear-aperture overflows clear `valid`;
invalid rays keep finite placeholder values (no NaN/Inf is returned).

Compiled because the lens levels trace many small batches (chief-ray aiming, pupil searches: a few
to a few hundred rays, thousands of times), where numpy's per-operation overhead was ~0.2 ms per
surface; the per-ray loop also needs no temporaries for the large batches of the ray-traced level.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit

from workbench.errors import InvalidValueError
from workbench.optics.lens.model import Lens, Surface

_T_MIN_MM = -1e-9
_NEWTON_ITERS = 30
_NEWTON_TOL_MM = 1e-10


@dataclass
class RayTrace:
    """Result of a trace. points/dirs: (N,3) after the last surface traced; valid: (N,) bool;
    opl_mm: optical path length from the start points (index × geometric length);
    path_mm: (n_surfaces+1, N, 3) start point and every intersection when recorded, else None."""

    points: np.ndarray
    dirs: np.ndarray
    valid: np.ndarray
    opl_mm: np.ndarray
    path_mm: np.ndarray | None = None


def _as_rays(points_mm, directions) -> tuple[np.ndarray, np.ndarray]:
    p = np.array(points_mm, dtype=np.float64, ndmin=2, copy=True, order="C")
    d = np.array(directions, dtype=np.float64, ndmin=2, copy=True, order="C")
    if p.ndim != 2 or p.shape[1] != 3 or d.shape != p.shape:
        raise InvalidValueError(f"rays: points {p.shape} and directions {d.shape} must both be (N, 3)")
    status = _check_and_normalise(p, d)
    if status == 1:
        raise InvalidValueError("rays: points and directions must be finite")
    if status == 2:
        raise InvalidValueError("rays: a direction is the zero vector")
    return p, d


# numba caches compiled code beside the module (or in the user cache); a frozen app has no source
_CACHE = not getattr(sys, "frozen", False)
_NO_PATH = np.empty((1, 1, 3))                  # the kernel's path argument when none is recorded


@njit(cache=_CACHE, nogil=True)
def _check_and_normalise(p, d):
    """0 when every point and direction is finite and no direction is zero (d is then made unit
    length in place), 1 for a non-finite value, 2 for a zero direction."""
    for j in range(p.shape[0]):
        for i in range(3):
            if not (math.isfinite(p[j, i]) and math.isfinite(d[j, i])):
                return 1
    for j in range(d.shape[0]):
        norm = math.sqrt(d[j, 0] * d[j, 0] + d[j, 1] * d[j, 1] + d[j, 2] * d[j, 2])
        if norm == 0.0:
            return 2
        d[j, 0], d[j, 1], d[j, 2] = d[j, 0] / norm, d[j, 1] / norm, d[j, 2] / norm
    return 0


@njit(cache=_CACHE, nogil=True)
def _sag_and_slope(c, kk, asph, n_asph, rho):
    """Sag z(ρ), dz/dρ with ρ = r², and whether the conic square root is defined."""
    arg = 1.0 - kk * c * c * rho
    ok = arg >= 0.0
    root = math.sqrt(arg if ok else 1.0)
    z = c * rho / (1.0 + root)
    dz = c / (2.0 * root)
    for i in range(n_asph):
        z += asph[i] * rho ** (i + 1)
        dz += (i + 1) * asph[i] * rho ** i
    return z, dz, ok


@njit(cache=_CACHE, nogil=True)
def _newton_asphere(c, kk, asph, n_asph, qx, qy, qz, dx, dy, dz, t):
    ok = True
    for _ in range(_NEWTON_ITERS):
        x, y, z = qx + t * dx, qy + t * dy, qz + t * dz
        s, ds, dom = _sag_and_slope(c, kk, asph, n_asph, x * x + y * y)
        fp = dz - 2.0 * ds * (x * dx + y * dy)
        ok = ok and dom and fp != 0.0
        step = (z - s) / fp if ok else 0.0
        t -= step
        if abs(step) < _NEWTON_TOL_MM:
            break
    x, y, z = qx + t * dx, qy + t * dy, qz + t * dz
    s, _, dom = _sag_and_slope(c, kk, asph, n_asph, x * x + y * y)
    ok = ok and dom and abs(z - s) < 1e-8 and math.isfinite(t)
    return ok, (t if ok else 0.0)


@njit(cache=_CACHE, nogil=True)
def _hit(c, kk, asph, n_asph, z_vertex_mm, x, y, z, dx, dy, dz):
    """(t, hit) for the ray (x, y, z) + t (dx, dy, dz) and the surface with vertex at z_vertex_mm."""
    qz = z - z_vertex_mm
    if c == 0.0 and n_asph == 0:                         # exact plane
        if dz == 0.0:
            return 0.0, False
        t = -qz / dz
        return (t, True) if t >= _T_MIN_MM else (0.0, False)
    a = c * (dx * dx + dy * dy + kk * dz * dz)
    b = c * (x * dx + y * dy + kk * qz * dz) - dz
    cc = c * (x * x + y * y + kk * qz * qz) - 2.0 * qz
    disc = b * b - a * cc
    hit = disc >= 0.0
    q = -(b + math.copysign(math.sqrt(disc) if hit else 0.0, b))
    best = math.inf
    if hit:
        for k in range(2):
            if k == 0:
                t = cc / q if q != 0.0 else math.inf
            else:
                t = q / a if a != 0.0 else math.inf
            if math.isfinite(t) and t >= _T_MIN_MM and t < best and kk * c * (qz + t * dz) <= 1.0 + 1e-12:
                best = t
    ok = math.isfinite(best)
    if n_asph:
        start = best if ok else (-qz / dz if dz != 0.0 else 0.0)
        conv, best = _newton_asphere(c, kk, asph, n_asph, x, y, qz, dx, dy, dz, start)
        ok = conv and best >= _T_MIN_MM
    return (best, True) if ok else (0.0, False)


@njit(cache=_CACHE, nogil=True)
def _normal(c, kk, asph, n_asph, z_vertex_mm, x, y, z):
    """Unit normal (pointing roughly +z) at a surface point."""
    if n_asph:
        _, ds, _ = _sag_and_slope(c, kk, asph, n_asph, x * x + y * y)
        nx, ny, nz = -2.0 * x * ds, -2.0 * y * ds, 1.0
    else:
        nx, ny, nz = -c * x, -c * y, 1.0 - c * kk * (z - z_vertex_mm)
    inv = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
    return nx * inv, ny * inv, nz * inv


@njit(cache=_CACHE, nogil=True)
def _refract(dx, dy, dz, nx, ny, nz, mu):
    """Snell's law (mu = n1/n2); returns (dx, dy, dz, ok), ok False at total internal reflection
    (the direction is then left unchanged)."""
    cosi = dx * nx + dy * ny + dz * nz
    sgn = -1.0 if cosi < 0.0 else 1.0
    cosi *= sgn
    k = 1.0 - mu * mu * (1.0 - cosi * cosi)
    if k < 0.0:
        return dx, dy, dz, False
    coef = (math.sqrt(k) - mu * cosi) * sgn
    ox, oy, oz = mu * dx + coef * nx, mu * dy + coef * ny, mu * dz + coef * nz
    inv = 1.0 / math.sqrt(ox * ox + oy * oy + oz * oz)
    return ox * inv, oy * inv, oz * inv, True


@njit(cache=_CACHE, nogil=True)
def _trace_kernel(p, d, curv, kk, asph, n_asph, zv, semi2, refracts, n_in, n_out, backward,
                  points, dirs, valid, opl, path, record):
    """Every ray through every surface of the table (travel order); fills points (mm), dirs (unit),
    valid, opl (mm) and, when record, path (mm). Per surface: curv (1/mm), kk = 1 + conic, asph
    (even-asphere coefficients, mm^(1−2i)) and their count, zv (vertex z, mm), semi2 (squared
    clear semi-aperture, mm²), refracts (not the stop). n_in/n_out: (S, 1) or (S, N) refractive
    indices before/after each surface."""
    per_ray = n_in.shape[1] > 1
    for j in range(p.shape[0]):
        x, y, z = p[j, 0], p[j, 1], p[j, 2]
        dx, dy, dz = d[j, 0], d[j, 1], d[j, 2]
        col = j if per_ray else 0
        length, t = 0.0, 0.0
        alive = True
        for k in range(curv.shape[0]):
            if alive:
                t, alive = _hit(curv[k], kk[k], asph[k], n_asph[k], zv[k], x, y, z, dx, dy, dz)
            if alive:
                hx, hy, hz = x + t * dx, y + t * dy, z + t * dz
                alive = hx * hx + hy * hy <= semi2[k]
                n1, n2 = n_in[k, col], n_out[k, col]
                if alive and refracts[k] and n1 != n2:
                    nx, ny, nz = _normal(curv[k], kk[k], asph[k], n_asph[k], zv[k], hx, hy, hz)
                    dx, dy, dz, alive = _refract(dx, dy, dz, nx, ny, nz, n1 / n2)
                if alive:                          # a ray that dies here stays where it was
                    x, y, z = hx, hy, hz
                    length += n1 * t
            if record:
                path[k + 1, j, 0], path[k + 1, j, 1], path[k + 1, j, 2] = x, y, z
        valid[j] = alive
        if alive:
            points[j, 0], points[j, 1], points[j, 2] = x, y, z
            dirs[j, 0], dirs[j, 1], dirs[j, 2] = dx, dy, dz
            opl[j] = length
        else:
            points[j, 0], points[j, 1], points[j, 2] = 0.0, 0.0, 0.0
            dirs[j, 0], dirs[j, 1], dirs[j, 2] = 0.0, 0.0, -1.0 if backward else 1.0
            opl[j] = 0.0


@njit(cache=_CACHE, nogil=True)
def _intersect_kernel(c, kk, asph, n_asph, z_vertex_mm, p, d, t, ok):
    for j in range(p.shape[0]):
        t[j], ok[j] = _hit(c, kk, asph, n_asph, z_vertex_mm, p[j, 0], p[j, 1], p[j, 2], d[j, 0], d[j, 1], d[j, 2])


@njit(cache=_CACHE, nogil=True)
def _normal_kernel(c, kk, asph, n_asph, z_vertex_mm, pts, out):
    for j in range(pts.shape[0]):
        out[j, 0], out[j, 1], out[j, 2] = _normal(c, kk, asph, n_asph, z_vertex_mm, pts[j, 0], pts[j, 1], pts[j, 2])


@njit(cache=_CACHE, nogil=True)
def _refract_kernel(d, normal, mu, out, ok):
    for j in range(d.shape[0]):
        m = mu[j] if mu.shape[0] > 1 else mu[0]
        out[j, 0], out[j, 1], out[j, 2], ok[j] = _refract(d[j, 0], d[j, 1], d[j, 2],
                                                          normal[j, 0], normal[j, 1], normal[j, 2], m)


def _surface_args(surface: Surface):
    """(c in 1/mm, 1 + k, aspheric coefficients padded with one 0, their count) of a surface, as
    the kernels take them."""
    coeffs = np.asarray(surface.asphere_coeffs if surface.is_aspheric else (), dtype=np.float64)
    return (float(surface.curvature_per_mm), 1.0 + float(surface.conic),
            np.append(coeffs, 0.0), int(coeffs.size))


@lru_cache(maxsize=256)
def _surface_table(lens: Lens, reverse: bool, n_surfaces: int | None):
    """The surfaces in travel order as kernel arrays, and their (medium in, medium out) pairs."""
    order = list(range(len(lens.surfaces)))
    if reverse:
        order = order[::-1]
    if n_surfaces is not None:
        order = order[:n_surfaces]
    media = lens.media()
    rows = [_surface_args(lens.surfaces[i]) for i in order]
    width = max(1, max((r[3] for r in rows), default=0))
    asph = np.zeros((len(order), width))
    for k, (_, _, coeffs, count) in enumerate(rows):
        asph[k, :count] = coeffs[:count]
    table = (np.array([r[0] for r in rows], dtype=np.float64), np.array([r[1] for r in rows], dtype=np.float64),
             asph, np.array([r[3] for r in rows], dtype=np.int64), lens.vertex_z_mm[order].astype(np.float64),
             np.array([lens.surfaces[i].semi_aperture_mm ** 2 for i in order], dtype=np.float64),
             np.array([not lens.surfaces[i].is_stop for i in order], dtype=np.bool_))
    for a in table:
        a.setflags(write=False)
    pairs = tuple((media[i + 1], media[i]) if reverse else (media[i], media[i + 1]) for i in order)
    return table, pairs


@lru_cache(maxsize=1024)
def _scalar_setup(lens: Lens, reverse: bool, n_surfaces: int | None, wavelength_nm: float):
    """The surface table and the (S, 1) indices before and after each surface at one wavelength
    (one cached lookup: aiming traces the same lens at the same wavelength thousands of times)."""
    table, pairs = _surface_table(lens, reverse, n_surfaces)
    n_in = np.array([float(a.index(wavelength_nm)) for a, _ in pairs], dtype=np.float64).reshape(-1, 1)
    n_out = np.array([float(b.index(wavelength_nm)) for _, b in pairs], dtype=np.float64).reshape(-1, 1)
    return table, n_in, n_out, len(pairs)       # (writable like the per-ray ones: one compiled kernel)


def intersect(surface: Surface, z_vertex_mm: float, p: np.ndarray, d: np.ndarray):
    """Distance t along unit rays (p, d) ((N,3) each) to `surface` (vertex at z_vertex_mm) and a
    hit mask. The clear aperture is not tested here."""
    p = np.ascontiguousarray(p, dtype=np.float64)
    d = np.ascontiguousarray(d, dtype=np.float64)
    t, ok = np.empty(p.shape[0]), np.empty(p.shape[0], dtype=np.bool_)
    _intersect_kernel(*_surface_args(surface), float(z_vertex_mm), p, d, t, ok)
    return t, ok


def surface_normal(surface: Surface, z_vertex_mm: float, pts: np.ndarray) -> np.ndarray:
    """Unit normals (pointing roughly +z) at (N,3) points on the surface."""
    pts = np.ascontiguousarray(pts, dtype=np.float64)
    out = np.empty_like(pts)
    _normal_kernel(*_surface_args(surface), float(z_vertex_mm), pts, out)
    return out


def refract(d: np.ndarray, normal: np.ndarray, n1, n2):
    """Snell's law in vector form for (N,3) unit directions and normals; returns (new directions,
    ok) with ok False at total internal reflection (the direction is then left unchanged)."""
    d = np.ascontiguousarray(d, dtype=np.float64)
    normal = np.ascontiguousarray(normal, dtype=np.float64)
    mu = np.atleast_1d(np.asarray(n1, dtype=np.float64) / np.asarray(n2, dtype=np.float64)).ravel()
    out, ok = np.empty_like(d), np.empty(d.shape[0], dtype=np.bool_)
    _refract_kernel(d, normal, np.ascontiguousarray(mu), out, ok)
    return out, ok


def trace_rays(lens: Lens, points_mm, directions, wavelength_nm, reverse: bool = False,
               n_surfaces: int | None = None, record: bool = False) -> RayTrace:
    """Trace rays through the first `n_surfaces` surfaces in travel order (all by default).
    Forward rays travel object → image (+z); reverse rays image → object (−z).
    `wavelength_nm` is a scalar or one value per ray. Dead rays' outputs are placeholders; in a
    recorded path a ray that died stays where it last was."""
    p, d = _as_rays(points_mm, directions)
    n = p.shape[0]
    wl = wavelength_nm if isinstance(wavelength_nm, float) else np.asarray(wavelength_nm, dtype=np.float64)
    if np.ndim(wl) not in (0, 1) or (np.ndim(wl) == 1 and wl.shape != (n,)):
        raise InvalidValueError(f"wavelength_nm: a scalar or one value per ray ({n}), got shape {wl.shape}")
    if not (np.all(np.isfinite(wl)) and np.all(wl > 0)):
        raise InvalidValueError(f"wavelength_nm: must be finite and > 0, got {wavelength_nm!r}")
    if np.ndim(wl) == 0:
        table, n_in, n_out, n_traced = _scalar_setup(lens, bool(reverse), n_surfaces, float(wl))
    else:
        table, pairs = _surface_table(lens, bool(reverse), n_surfaces)
        index = {id(m): np.asarray(m.index(wl), dtype=np.float64) * np.ones(n) for pair in pairs for m in pair}
        n_in = np.array([index[id(a)] for a, _ in pairs]).reshape(len(pairs), n)
        n_out = np.array([index[id(b)] for _, b in pairs]).reshape(len(pairs), n)
        n_traced = len(pairs)
    points, dirs = np.empty((n, 3)), np.empty((n, 3))
    valid, opl = np.empty(n, dtype=np.bool_), np.empty(n)
    path = np.repeat(p[None], n_traced + 1, axis=0) if record else _NO_PATH
    _trace_kernel(p, d, *table, n_in, n_out, bool(reverse), points, dirs, valid, opl, path, bool(record))
    return RayTrace(points, dirs, valid, opl, path if record else None)


def trace_from_object(lens: Lens, points_mm, directions, wavelength_nm):
    """Object → image. Rays (N,3) in lens coordinates (first vertex at z = 0, +z towards the image).
    Returns (points on the last surface, unit directions after it, valid mask)."""
    r = trace_rays(lens, points_mm, directions, wavelength_nm)
    return r.points, r.dirs, r.valid


def trace_from_sensor(lens: Lens, points_mm, directions, wavelength_nm):
    """Image → object (directions with dz < 0). Returns (points on the first surface, unit
    directions into object space, valid mask)."""
    r = trace_rays(lens, points_mm, directions, wavelength_nm, reverse=True)
    return r.points, r.dirs, r.valid


def to_plane(points: np.ndarray, dirs: np.ndarray, valid: np.ndarray, z_mm: float):
    """Propagate rays to the plane z = z_mm; returns (points, valid) (rays parallel to it fail)."""
    dz = dirs[:, 2]
    ok = valid & (np.abs(dz) > 1e-15)
    t = np.where(ok, (z_mm - points[:, 2]) / np.where(ok, dz, 1.0), 0.0)
    return points + t[:, None] * dirs, ok

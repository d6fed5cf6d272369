"""Real-ray tracing through a sequential lens, vectorised in float64.

Intersection is vertex-relative: for the conic c(x² + y² + (1+k) z²) − 2z = 0 the ray p + t·d gives
A t² + 2b t + C = 0 with the stable roots q = −(b + sign(b)√(b² − AC)), t = C/q and q/A — exact for a
flat surface (A = 0) and free of cancellation for nearly flat ones. The root kept is the nearest one
ahead of the ray on the vertex branch ((1+k) c z ≤ 1). Even aspheres are refined by Newton's method
from the conic hit. Misses, total internal reflection and clear-aperture overflows clear `valid`;
invalid rays keep finite placeholder values (no NaN/Inf is returned).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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
    p = np.array(points_mm, dtype=np.float64, ndmin=2, copy=True)
    d = np.array(directions, dtype=np.float64, ndmin=2, copy=True)
    if p.ndim != 2 or p.shape[1] != 3 or d.shape != p.shape:
        raise InvalidValueError(f"rays: points {p.shape} and directions {d.shape} must both be (N, 3)")
    if not (np.isfinite(p).all() and np.isfinite(d).all()):
        raise InvalidValueError("rays: points and directions must be finite")
    norm = np.linalg.norm(d, axis=1)
    if np.any(norm == 0):
        raise InvalidValueError("rays: a direction is the zero vector")
    return p, d / norm[:, None]


def _hit_distance(surface: Surface, z_vertex_mm: float, x, y, z, dx, dy, dz):
    """Structure-of-arrays kernel of `intersect`: (t, hit) for rays (x, y, z) + t (dx, dy, dz)."""
    qz = z - z_vertex_mm
    c, kk = surface.curvature_per_mm, 1.0 + surface.conic
    if c == 0.0 and not surface.is_aspheric:             # exact plane
        moving = dz != 0.0
        t = -qz / np.where(moving, dz, 1.0)
        ok = moving & (t >= _T_MIN_MM)
        return np.where(ok, t, 0.0), ok
    A = c * (dx * dx + dy * dy + kk * dz * dz)
    b = c * (x * dx + y * dy + kk * qz * dz) - dz
    C = c * (x * x + y * y + kk * qz * qz) - 2.0 * qz
    disc = b * b - A * C
    hit = disc >= 0
    q = -(b + np.copysign(np.sqrt(np.where(hit, disc, 0.0)), b))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        t1 = np.where(q != 0, C / np.where(q != 0, q, 1.0), np.inf)
        t2 = np.where(A != 0, q / np.where(A != 0, A, 1.0), np.inf)
    best = np.full(x.shape, np.inf)
    for t in (t1, t2):
        fin = np.isfinite(t)
        zt = qz + np.where(fin, t, 0.0) * dz
        ok = hit & fin & (t >= _T_MIN_MM) & (kk * c * zt <= 1.0 + 1e-12)
        best = np.where(ok & (t < best), t, best)
    ok = np.isfinite(best)
    if surface.is_aspheric:
        flat_t = np.where(dz != 0, -qz / np.where(dz != 0, dz, 1.0), 0.0)
        conv, t = _newton_asphere(surface, x, y, qz, dx, dy, dz, np.where(ok, best, flat_t))
        ok = conv & (t >= _T_MIN_MM)
        best = t
    return np.where(ok, best, 0.0), ok


def intersect(surface: Surface, z_vertex_mm: float, p: np.ndarray, d: np.ndarray):
    """Distance t along unit rays (p, d) ((N,3) each) to `surface` (vertex at z_vertex_mm) and a
    hit mask. The clear aperture is not tested here."""
    return _hit_distance(surface, z_vertex_mm, p[:, 0], p[:, 1], p[:, 2], d[:, 0], d[:, 1], d[:, 2])


def _sag_and_slope(surface: Surface, rho: np.ndarray):
    """Sag z(ρ) and dz/dρ with ρ = r²; also the mask where the conic square root is defined."""
    c, kk = surface.curvature_per_mm, 1.0 + surface.conic
    arg = 1.0 - kk * c * c * rho
    ok = arg >= 0
    root = np.sqrt(np.where(ok, arg, 1.0))
    z = c * rho / (1.0 + root)
    dz = c / (2.0 * root)
    for i, a in enumerate(surface.asphere_coeffs):
        z = z + a * rho ** (i + 1)
        dz = dz + (i + 1) * a * rho ** i
    return z, dz, ok


def _newton_asphere(surface, qx, qy, qz, dx, dy, dz, t):
    ok = np.ones(t.shape, bool)
    for _ in range(_NEWTON_ITERS):
        x, y, z = qx + t * dx, qy + t * dy, qz + t * dz
        s, ds, dom = _sag_and_slope(surface, x * x + y * y)
        f = z - s
        fp = dz - 2.0 * ds * (x * dx + y * dy)
        ok &= dom & (fp != 0)
        step = np.where(ok, f / np.where(fp != 0, fp, 1.0), 0.0)
        t = t - step
        if np.all(np.abs(step) < _NEWTON_TOL_MM):
            break
    x, y, z = qx + t * dx, qy + t * dy, qz + t * dz
    s, _, dom = _sag_and_slope(surface, x * x + y * y)
    ok &= dom & (np.abs(z - s) < 1e-8) & np.isfinite(t)
    return ok, np.where(ok, t, 0.0)


def _normal(surface: Surface, z_vertex_mm: float, x, y, z):
    """Unit normal components (pointing roughly +z) at surface points."""
    c, kk = surface.curvature_per_mm, 1.0 + surface.conic
    if surface.is_aspheric:
        _, ds, _ = _sag_and_slope(surface, x * x + y * y)
        nx, ny, nz = -2.0 * x * ds, -2.0 * y * ds, np.ones_like(x)
    else:
        nx, ny, nz = -c * x, -c * y, 1.0 - c * kk * (z - z_vertex_mm)
    inv = 1.0 / np.sqrt(nx * nx + ny * ny + nz * nz)
    return nx * inv, ny * inv, nz * inv


def surface_normal(surface: Surface, z_vertex_mm: float, pts: np.ndarray) -> np.ndarray:
    """Unit normals (pointing roughly +z) at (N,3) points on the surface."""
    return np.column_stack(_normal(surface, z_vertex_mm, pts[:, 0], pts[:, 1], pts[:, 2]))


def _refract(dx, dy, dz, nx, ny, nz, mu):
    """Structure-of-arrays Snell's law (mu = n1/n2); returns (dx, dy, dz, ok), ok False at TIR
    (the direction is then left unchanged)."""
    cosi = dx * nx + dy * ny + dz * nz
    sgn = np.where(cosi < 0, -1.0, 1.0)
    cosi = cosi * sgn
    k = 1.0 - mu * mu * (1.0 - cosi * cosi)
    ok = k >= 0
    coef = (np.sqrt(np.where(ok, k, 0.0)) - mu * cosi) * sgn
    ox, oy, oz = mu * dx + coef * nx, mu * dy + coef * ny, mu * dz + coef * nz
    inv = 1.0 / np.sqrt(ox * ox + oy * oy + oz * oz)
    return (np.where(ok, ox * inv, dx), np.where(ok, oy * inv, dy), np.where(ok, oz * inv, dz), ok)


def refract(d: np.ndarray, normal: np.ndarray, n1, n2):
    """Snell's law in vector form for (N,3) unit directions and normals; returns (new directions,
    ok) with ok False at total internal reflection (the direction is then left unchanged)."""
    mu = np.asarray(n1, dtype=np.float64) / np.asarray(n2, dtype=np.float64)
    ox, oy, oz, ok = _refract(d[:, 0], d[:, 1], d[:, 2], normal[:, 0], normal[:, 1], normal[:, 2], mu)
    return np.column_stack([ox, oy, oz]), ok


def trace_rays(lens: Lens, points_mm, directions, wavelength_nm, reverse: bool = False,
               n_surfaces: int | None = None, record: bool = False) -> RayTrace:
    """Trace rays through the first `n_surfaces` surfaces in travel order (all by default).
    Forward rays travel object → image (+z); reverse rays image → object (−z).
    `wavelength_nm` is a scalar or one value per ray. Rays that die are dropped from the working
    arrays as they die (their outputs are placeholders)."""
    p, d = _as_rays(points_mm, directions)
    n = p.shape[0]
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    if wl.ndim not in (0, 1) or (wl.ndim == 1 and wl.shape != (n,)):
        raise InvalidValueError(f"wavelength_nm: a scalar or one value per ray ({n}), got shape {wl.shape}")
    if np.any(~np.isfinite(wl)) or np.any(wl <= 0):
        raise InvalidValueError(f"wavelength_nm: must be finite and > 0, got {wavelength_nm!r}")
    media = lens.media()
    zv = lens.vertex_z_mm
    order = list(range(len(lens.surfaces)))
    if reverse:
        order = order[::-1]
    if n_surfaces is not None:
        order = order[:n_surfaces]
    x, y, z = p[:, 0].copy(), p[:, 1].copy(), p[:, 2].copy()
    dx, dy, dz = d[:, 0].copy(), d[:, 1].copy(), d[:, 2].copy()
    alive = np.arange(n)
    opl = np.zeros(n)
    path = np.repeat(p[None], len(order) + 1, axis=0) if record else None
    index_cache: dict[int, np.ndarray | float] = {}

    def index(m):
        if id(m) not in index_cache:
            index_cache[id(m)] = m.index(wl) if wl.ndim == 0 else np.asarray(m.index(wl))
        v = index_cache[id(m)]
        return v if np.ndim(v) == 0 else v[alive]

    for k, i in enumerate(order):
        s = lens.surfaces[i]
        m_in, m_out = (media[i + 1], media[i]) if reverse else (media[i], media[i + 1])
        if alive.size:
            t, good = _hit_distance(s, zv[i], x, y, z, dx, dy, dz)
            x, y, z = x + t * dx, y + t * dy, z + t * dz
            good &= x * x + y * y <= s.semi_aperture_mm ** 2
            n1, n2 = index(m_in), index(m_out)
            opl = opl + n1 * t
            if not s.is_stop and not (np.ndim(n1) == 0 and np.ndim(n2) == 0 and n1 == n2):
                nx, ny, nz = _normal(s, zv[i], x, y, z)
                dx, dy, dz, ok = _refract(dx, dy, dz, nx, ny, nz, n1 / n2)
                good &= ok
            if not good.all():
                x, y, z, dx, dy, dz, opl, alive = (a[good] for a in (x, y, z, dx, dy, dz, opl, alive))
        if record:
            path[k + 1] = path[k]
            path[k + 1, alive] = np.column_stack([x, y, z])
    valid = np.zeros(n, bool)
    valid[alive] = True
    points = np.zeros((n, 3))
    points[alive] = np.column_stack([x, y, z])
    dirs = np.tile([0.0, 0.0, -1.0 if reverse else 1.0], (n, 1))
    dirs[alive] = np.column_stack([dx, dy, dz])
    opl_out = np.zeros(n)
    opl_out[alive] = opl
    return RayTrace(points, dirs, valid, opl_out, path)


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

"""Object-side ray bundles: pupil boxes (PBRT-style bounds of the rays that pass) and chief-ray aiming.

A field is given by its angle θ (deg): rays rise towards +y and land at +y on the sensor. For an
object at distance D (mm in front of the first vertex) the object point is (0, −D tanθ, −D).
Rays are parameterised by (u, v) on the plane through the first vertex perpendicular to the central
direction d0 (u along x, v in the y–z plane); at infinity every ray starts on one such plane, so the
optical path from the start is the path from a common wavefront.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from workbench.errors import InvalidValueError
from workbench.optics.lens.model import Lens
from workbench.optics.lens.paraxial import sensor_z_mm, with_aperture_stop
from workbench.optics.lens.trace import RayTrace, to_plane, trace_rays

_COARSE = 64
CHIEF_RAY_CACHE_SIZE = 4096    # aimed chief rays and field angles kept (a few floats each)


@dataclass(frozen=True)
class Bundle:
    """Ray source for one field: build rays with `rays(u, v)`; `box` bounds the passing (u, v)."""

    lens: Lens
    field_angle_deg: float
    object_distance_mm: float          # inf for an object at infinity
    box: tuple[float, float, float, float]   # u0, u1, v0, v1

    @property
    def d0(self) -> np.ndarray:
        t = math.radians(self.field_angle_deg)
        return np.array([0.0, math.sin(t), math.cos(t)])

    def rays(self, u, v) -> tuple[np.ndarray, np.ndarray]:
        u = np.asarray(u, dtype=np.float64).ravel()
        v = np.asarray(v, dtype=np.float64).ravel()
        t = math.radians(self.field_angle_deg)
        ev = np.array([0.0, math.cos(t), -math.sin(t)])
        target = u[:, None] * np.array([1.0, 0.0, 0.0]) + v[:, None] * ev
        if math.isinf(self.object_distance_mm):
            lead = 2.0 * _reach_mm(self.lens) + 1.0
            return target - lead * self.d0, np.broadcast_to(self.d0, target.shape).copy()
        src = np.array([0.0, -self.object_distance_mm * math.tan(t), -self.object_distance_mm])
        d = target - src
        return np.broadcast_to(src, target.shape).copy(), d / np.linalg.norm(d, axis=1)[:, None]

    def trace(self, u, v, wavelength_nm, **kw) -> RayTrace:
        p, d = self.rays(u, v)
        return trace_rays(self.lens, p, d, wavelength_nm, **kw)

    def grid(self, n_side: int) -> tuple[np.ndarray, np.ndarray, float, float]:
        """(u, v) of an n×n grid of cell centres over the box, and the cell sizes du, dv."""
        u0, u1, v0, v1 = self.box
        du, dv = (u1 - u0) / n_side, (v1 - v0) / n_side
        uu, vv = np.meshgrid(u0 + du * (np.arange(n_side) + 0.5), v0 + dv * (np.arange(n_side) + 0.5))
        return uu.ravel(), vv.ravel(), du, dv


def _reach_mm(lens: Lens) -> float:
    """Radius of a sphere about the first vertex that holds the first surface's clear aperture."""
    s = lens.surfaces[0]
    return math.hypot(s.semi_aperture_mm, float(s.sag_mm(s.semi_aperture_mm))) * 1.02 + 1e-3


def make_bundle(lens: Lens, field_angle_deg: float, object_distance_m: float, wavelength_nm: float,
                n_coarse: int = _COARSE) -> Bundle:
    """The bundle for a field with its pupil box (bounds of the (u, v) that pass, padded one step).
    ValueError when no ray of the field passes through the lens."""
    if not (-90.0 < field_angle_deg < 90.0):
        raise InvalidValueError(f"field_angle_deg={field_angle_deg}: must be in (−90, 90)")
    if not object_distance_m > 0:
        raise InvalidValueError(f"object_distance_m={object_distance_m}: must be > 0 (or inf)")
    D = object_distance_m * 1e3
    rho = _reach_mm(lens)
    if math.isfinite(D):
        if D <= rho * 1.5:
            raise InvalidValueError(f"object_distance_m={object_distance_m}: object is inside or touching the lens")
        rho = rho * D / math.sqrt(D * D - rho * rho)
    from workbench.optics.lens.paraxial import paraxial
    par = paraxial(lens, wavelength_nm)
    t = math.radians(field_angle_deg)
    v_ep = -par.entrance_pupil_mm * math.sin(t)        # paraxial entrance-pupil centre on the plane
    r_ep = 3.0 * par.epd_mm / 2 + 1e-6
    for cu, cv, half in ((0.0, 0.0, rho), (0.0, v_ep, min(r_ep, rho))):
        b = Bundle(lens, float(field_angle_deg), D, (cu - half, cu + half, cv - half, cv + half))
        u, v, du, dv = b.grid(n_coarse)
        ok = b.trace(u, v, wavelength_nm).valid
        if ok.any():
            break
    if not ok.any():
        raise InvalidValueError(f"lens {lens.name!r}: no ray from field {field_angle_deg:g}° "
                         f"(object at {object_distance_m:g} m) passes through the lens")
    box = (max(u[ok].min() - du, -rho), min(u[ok].max() + du, rho),
           max(v[ok].min() - dv, -rho), min(v[ok].max() + dv, rho))
    return Bundle(lens, float(field_angle_deg), D, box)


def chief_ray_v(bundle: Bundle, wavelength_nm: float, n_scan: int = 401) -> float:
    """v of the chief ray (u = 0): the ray through the centre of the stop.
    ValueError when no ray of the field reaches the stop centre."""
    k = with_aperture_stop(bundle.lens).stop_index
    _, _, v0, v1 = bundle.box
    v = np.linspace(v0, v1, n_scan)

    def y_at_stop(vs):
        r = bundle.trace(np.zeros_like(vs), vs, wavelength_nm, n_surfaces=k + 1)
        return r.points[:, 1], r.valid

    y, ok = y_at_stop(v)
    cross = np.nonzero(ok[:-1] & ok[1:] & (np.sign(y[:-1]) != np.sign(y[1:])))[0]
    exact = np.nonzero(ok & (y == 0))[0]
    if exact.size:
        return float(v[exact[0]])
    if not cross.size:
        raise InvalidValueError(f"lens {bundle.lens.name!r}: no ray from field {bundle.field_angle_deg:g}° "
                         "passes through the centre of the stop (chief ray cannot be aimed)")
    i = cross[0]
    a, b, ya, yb = v[i], v[i + 1], y[i], y[i + 1]
    for _ in range(40):  # bracketed secant (Illinois) — robust and fast
        m = b - yb * (b - a) / (yb - ya)
        (ym,), (okm,) = y_at_stop(np.array([m]))
        if not okm:
            m = 0.5 * (a + b)
            (ym,), (okm,) = y_at_stop(np.array([m]))
        if not okm:
            raise InvalidValueError(f"lens {bundle.lens.name!r}: the chief ray of field {bundle.field_angle_deg:g}° "
                             "is blocked before the stop")
        if abs(ym) < 1e-12 or abs(b - a) < 1e-13:
            return float(m)
        if np.sign(ym) == np.sign(yb):
            b, yb = m, ym
            ya *= 0.5
        else:
            a, ya = b, yb
            b, yb = m, ym
    return float(m)


def chief_ray_on_sensor(lens: Lens, field_angle_deg: float, wavelength_nm: float,
                        object_distance_m: float = math.inf, bundle: Bundle | None = None):
    """(x, y) in mm where the chief ray meets the sensor plane. ValueError if it cannot be traced.
    Without a bundle the result is cached per (lens, field, wavelength, distance): the PSF grid,
    the lens tables and the level selector aim the same chief rays again and again."""
    if bundle is None:
        return _chief_ray_on_sensor(lens, float(field_angle_deg), float(wavelength_nm), float(object_distance_m))
    return _aim_chief_ray(lens, field_angle_deg, wavelength_nm, bundle)


@lru_cache(maxsize=CHIEF_RAY_CACHE_SIZE)
def _chief_ray_on_sensor(lens: Lens, field_angle_deg: float, wavelength_nm: float, object_distance_m: float):
    return _aim_chief_ray(lens, field_angle_deg, wavelength_nm,
                          make_bundle(lens, field_angle_deg, object_distance_m, wavelength_nm))


def _aim_chief_ray(lens: Lens, field_angle_deg: float, wavelength_nm: float, b: Bundle) -> tuple[float, float]:
    vc = chief_ray_v(b, wavelength_nm)
    r = b.trace(np.array([0.0]), np.array([vc]), wavelength_nm)
    pts, ok = to_plane(r.points, r.dirs, r.valid, sensor_z_mm(lens))
    if not ok[0]:
        raise InvalidValueError(f"lens {lens.name!r}: the chief ray of field {field_angle_deg:g}° is "
                         "vignetted before the sensor")
    return float(pts[0, 0]), float(pts[0, 1])


def field_angle_for_height(lens: Lens, image_height_mm: float, wavelength_nm: float,
                           object_distance_m: float = math.inf) -> float:
    """Field angle (deg) whose chief ray lands at `image_height_mm` on the sensor (secant search
    from the paraxial guess, cached). ValueError when the height is beyond what the lens images."""
    return _field_angle_for_height(lens, float(image_height_mm), float(wavelength_nm), float(object_distance_m))


@lru_cache(maxsize=CHIEF_RAY_CACHE_SIZE)
def _field_angle_for_height(lens: Lens, image_height_mm: float, wavelength_nm: float,
                            object_distance_m: float) -> float:
    from workbench.optics.lens.paraxial import paraxial
    if image_height_mm == 0:
        return 0.0
    f = paraxial(lens, wavelength_nm).efl_mm
    h_target = float(image_height_mm)

    def h_of(theta):
        return chief_ray_on_sensor(lens, theta, wavelength_nm, object_distance_m)[1]

    t0 = math.degrees(math.atan(h_target / f))
    t1 = t0 * 1.01 if t0 else 1e-3
    try:
        h0, h1 = h_of(t0), h_of(t1)
        for _ in range(30):
            if h1 == h0:
                break
            t2 = float(np.clip(t1 + (h_target - h1) * (t1 - t0) / (h1 - h0), -89.0, 89.0))
            t0, h0, t1 = t1, h1, t2
            h1 = h_of(t1)
            if abs(h1 - h_target) < 1e-9:
                return t1
    except ValueError as exc:
        raise InvalidValueError(f"image height {image_height_mm:g} mm of lens {lens.name!r} cannot be "
                         f"reached by a chief ray: {exc}") from None
    if abs(h1 - h_target) > 1e-6:
        raise InvalidValueError(f"image height {image_height_mm:g} mm of lens {lens.name!r}: chief-ray "
                         f"search did not converge (reached {h1:.6g} mm)")
    return t1

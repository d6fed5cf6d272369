"""Aberration analysis by real rays: spot diagrams, ray fans, distortion, relative illumination,
lateral and axial colour. Image-plane quantities are taken on the lens's sensor plane
(its current focus); field angles rise towards +y and land at +y.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.errors import InvalidValueError
from workbench.optics.lens.glass import LINE_C_NM, LINE_D_NM, LINE_F_NM
from workbench.optics.lens.model import Lens
from workbench.optics.lens.paraxial import paraxial, sensor_z_mm
from workbench.optics.lens.pupil import Bundle, chief_ray_on_sensor, chief_ray_v, make_bundle
from workbench.optics.lens.trace import to_plane, trace_rays


def _sensor_hits(bundle: Bundle, u, v, wavelength_nm):
    r = bundle.trace(u, v, wavelength_nm)
    pts, ok = to_plane(r.points, r.dirs, r.valid, sensor_z_mm(bundle.lens))
    return pts[:, :2], ok, r


@dataclass(frozen=True)
class SpotDiagram:
    """Ray landing points relative to the chief ray (µm), their RMS radius about the centroid."""

    field_angle_deg: float
    wavelength_nm: float
    x_um: np.ndarray
    y_um: np.ndarray
    rms_um: float
    centroid_um: tuple[float, float]
    chief_height_mm: float


def spot_diagram(lens: Lens, field_angle_deg: float, wavelength_nm: float = LINE_D_NM,
                 object_distance_m: float = math.inf, n_side: int = 32) -> SpotDiagram:
    """Spot diagram for a field from a uniform n_side² grid over the pupil box."""
    b = make_bundle(lens, field_angle_deg, object_distance_m, wavelength_nm)
    cx, cy = chief_ray_on_sensor(lens, field_angle_deg, wavelength_nm, object_distance_m, bundle=b)
    u, v, _, _ = b.grid(n_side)
    xy, ok, _ = _sensor_hits(b, u, v, wavelength_nm)
    if not ok.any():
        raise InvalidValueError(f"spot_diagram: no ray of field {field_angle_deg:g}° reaches the sensor")
    x = (xy[ok, 0] - cx) * 1e3
    y = (xy[ok, 1] - cy) * 1e3
    mx, my = float(x.mean()), float(y.mean())
    rms = float(np.sqrt(np.mean((x - mx) ** 2 + (y - my) ** 2)))
    return SpotDiagram(float(field_angle_deg), float(wavelength_nm), x, y, rms, (mx, my), cy)


@dataclass(frozen=True)
class RayFan:
    """Transverse ray errors (µm, relative to the chief ray) against normalised pupil coordinate."""

    field_angle_deg: float
    wavelength_nm: float
    pupil_t: np.ndarray
    error_t_um: np.ndarray      # y error along the tangential (meridional) fan
    valid_t: np.ndarray
    pupil_s: np.ndarray
    error_s_um: np.ndarray      # x error along the sagittal fan
    valid_s: np.ndarray


def _valid_span(bundle: Bundle, wavelength_nm: float, along_v: bool, through: float, n_scan: int = 801):
    """(lo, hi) of the line u = 0 (along_v) or v = through (along u) over which rays pass."""
    u0, u1, v0, v1 = bundle.box
    t = np.linspace(v0, v1, n_scan) if along_v else np.linspace(u0, u1, n_scan)
    other = np.full(n_scan, 0.0 if along_v else through)
    _, ok, _ = _sensor_hits(bundle, other if along_v else t, t if along_v else other, wavelength_nm)
    if not ok.any():
        return through, through
    return float(t[ok].min()), float(t[ok].max())


def ray_fan(lens: Lens, field_angle_deg: float, wavelength_nm: float = LINE_D_NM,
            object_distance_m: float = math.inf, n: int = 41) -> RayFan:
    """Tangential and sagittal ray fans across the passing part of the pupil (pupil coordinates in
    mm on the bundle's start plane, relative to the chief ray); vignetted samples are marked
    invalid with error 0."""
    b = make_bundle(lens, field_angle_deg, object_distance_m, wavelength_nm)
    vc = chief_ray_v(b, wavelength_nm)
    cx, cy = chief_ray_on_sensor(lens, field_angle_deg, wavelength_nm, object_distance_m, bundle=b)
    lo, hi = _valid_span(b, wavelength_nm, True, vc)
    vt = np.linspace(lo, hi, n)
    xy, ok_t, _ = _sensor_hits(b, np.zeros(n), vt, wavelength_nm)
    et = np.where(ok_t, (xy[:, 1] - cy) * 1e3, 0.0)
    lo, hi = _valid_span(b, wavelength_nm, False, vc)
    half = max(-lo, hi)
    us = np.linspace(-half, half, n)
    xy, ok_s, _ = _sensor_hits(b, us, np.full(n, vc), wavelength_nm)
    es = np.where(ok_s, (xy[:, 0] - cx) * 1e3, 0.0)
    return RayFan(float(field_angle_deg), float(wavelength_nm), vt - vc, et, ok_t, us, es, ok_s)


@dataclass(frozen=True)
class Distortion:
    """Chief-ray image height against the paraxial f·tanθ; invalid fields (chief ray not traceable)
    have valid False and zeros."""

    field_angles_deg: np.ndarray
    real_height_mm: np.ndarray
    paraxial_height_mm: np.ndarray
    distortion_percent: np.ndarray
    valid: np.ndarray


def distortion(lens: Lens, field_angles_deg, wavelength_nm: float = LINE_D_NM) -> Distortion:
    """Distortion (%) = (h_real − f tanθ)/(f tanθ)·100 for an object at infinity; 0 % on axis."""
    angles = np.atleast_1d(np.asarray(field_angles_deg, dtype=np.float64))
    f = paraxial(lens, wavelength_nm).efl_mm
    real = np.zeros_like(angles)
    ok = np.zeros(angles.shape, bool)
    for i, a in enumerate(angles):
        try:
            real[i] = chief_ray_on_sensor(lens, float(a), wavelength_nm)[1]
            ok[i] = True
        except ValueError:
            pass
    ideal = f * np.tan(np.radians(angles))
    with np.errstate(divide="ignore", invalid="ignore"):
        pct = np.where(ok & (ideal != 0), (real - ideal) / np.where(ideal != 0, ideal, 1.0) * 100.0, 0.0)
    return Distortion(angles, real, ideal, pct, ok)


def real_fov_deg(lens: Lens, sensor_size_mm: float, wavelength_nm: float = LINE_D_NM) -> float:
    """Full field of view (deg) across `sensor_size_mm` by real chief rays (distortion included),
    for an object at infinity; ValueError when the sensor edge is beyond the imaged field."""
    from workbench.optics.lens.pupil import field_angle_for_height
    if not (math.isfinite(sensor_size_mm) and sensor_size_mm > 0):
        raise InvalidValueError(f"sensor_size_mm={sensor_size_mm}: must be a finite number > 0")
    return 2.0 * field_angle_for_height(lens, sensor_size_mm / 2.0, wavelength_nm)


def lateral_color(lens: Lens, field_angles_deg, short_nm: float = LINE_F_NM,
                  long_nm: float = LINE_C_NM) -> tuple[np.ndarray, np.ndarray]:
    """Lateral colour (µm): chief-ray height at short_nm minus at long_nm, each aimed at its own
    wavelength, on the sensor. Returns (values, valid)."""
    angles = np.atleast_1d(np.asarray(field_angles_deg, dtype=np.float64))
    out = np.zeros_like(angles)
    ok = np.zeros(angles.shape, bool)
    for i, a in enumerate(angles):
        try:
            hs = chief_ray_on_sensor(lens, float(a), short_nm)[1]
            hl = chief_ray_on_sensor(lens, float(a), long_nm)[1]
            out[i], ok[i] = (hs - hl) * 1e3, True
        except ValueError:
            pass
    return out, ok


def axial_color(lens: Lens, short_nm: float = LINE_F_NM, long_nm: float = LINE_C_NM) -> float:
    """Axial (longitudinal) colour in mm: paraxial BFL(short) − BFL(long)."""
    return paraxial(lens, short_nm).bfl_mm - paraxial(lens, long_nm).bfl_mm


def _rear_rays(lens: Lens, image_height_mm: float, xy: np.ndarray):
    zs = sensor_z_mm(lens)
    zr = lens.total_track_mm
    src = np.array([0.0, image_height_mm, zs])
    tgt = np.column_stack([xy, np.full(len(xy), zr)])
    d = tgt - src
    return np.broadcast_to(src, d.shape).copy(), d / np.linalg.norm(d, axis=1)[:, None], zs - zr


def rear_pupil_box(lens: Lens, image_height_mm: float, wavelength_nm: float = LINE_D_NM,
                   n_coarse: int = 64) -> tuple[float, float, float, float] | None:
    """Bounds (x0, x1, y0, y1) in mm, on the plane of the last vertex, of the rays from a sensor
    point that pass back through the whole lens (PBRT's exit-pupil bounds); None if none pass.
    Searched over 1.5× the rear aperture, then (for small stops) around the paraxial exit pupil's
    projection."""
    last = lens.surfaces[-1]
    R = 1.5 * last.semi_aperture_mm + abs(float(last.sag_mm(last.semi_aperture_mm)))
    regions = [(0.0, 0.0, R)]
    p = paraxial(lens, wavelength_nm)
    zs, zr = sensor_z_mm(lens), lens.total_track_mm
    z_xp = zr + p.exit_pupil_mm
    if math.isfinite(z_xp) and abs(zs - z_xp) > 1e-9:
        k = (zs - zr) / (zs - z_xp)
        regions.append((image_height_mm * (1 - k), 0.0, max(3.0 * k * p.exit_pupil_diameter_mm / 2, 1e-6)))
    for cy, cx, half in regions:
        g = (np.arange(n_coarse) + 0.5) / n_coarse * 2 * half - half
        xx, yy = np.meshgrid(g + cx, g + cy)
        xy = np.column_stack([xx.ravel(), yy.ravel()])
        p0, d, _ = _rear_rays(lens, image_height_mm, xy)
        ok = trace_rays(lens, p0, d, wavelength_nm, reverse=True).valid
        if ok.any():
            step = 2 * half / n_coarse
            return (xy[ok, 0].min() - step, xy[ok, 0].max() + step,
                    xy[ok, 1].min() - step, xy[ok, 1].max() + step)
    return None


def irradiance_per_radiance(lens: Lens, image_height_mm: float = 0.0, wavelength_nm: float = LINE_D_NM,
                            n_side: int = 128) -> float:
    """Sensor irradiance per unit scene radiance (sr) at an image height, for a uniform scene:
    ∫ cos⁴θ / z² dA over the rear-vertex plane, counting the rays that pass back through the lens
    (the camera equation as PBRT's realistic camera evaluates it; π/(4N²) for an ideal lens)."""
    box = rear_pupil_box(lens, image_height_mm, wavelength_nm)
    if box is None:
        return 0.0
    x0, x1, y0, y1 = box
    dx, dy = (x1 - x0) / n_side, (y1 - y0) / n_side
    xx, yy = np.meshgrid(x0 + dx * (np.arange(n_side) + 0.5), y0 + dy * (np.arange(n_side) + 0.5))
    xy = np.column_stack([xx.ravel(), yy.ravel()])
    p, d, z = _rear_rays(lens, image_height_mm, xy)
    ok = trace_rays(lens, p, d, wavelength_nm, reverse=True).valid
    cos = -d[:, 2]
    return float(np.sum(np.where(ok, cos ** 4, 0.0)) * dx * dy / (z * z))


def relative_illumination(lens: Lens, field_heights_mm, wavelength_nm: float = LINE_D_NM,
                          n_side: int = 128) -> np.ndarray:
    """Irradiance at each image height relative to the axis, for a uniform scene (vignetting,
    cos⁴ and pupil aberration included)."""
    h = np.atleast_1d(np.asarray(field_heights_mm, dtype=np.float64))
    e0 = irradiance_per_radiance(lens, 0.0, wavelength_nm, n_side)
    if e0 <= 0:
        raise InvalidValueError(f"lens {lens.name!r}: no ray reaches the centre of the sensor")
    return np.array([irradiance_per_radiance(lens, float(x), wavelength_nm, n_side) / e0 for x in h])

"""The visible sun: its disc composited onto a pinhole radiance render where camera rays reach the sky.

The sun lights the scene as Mitsuba's `directional` emitter (a delta light: noise-free, but no
camera ray can see it). The disc is added afterwards: a uniform disc of angular radius
SUN_ANGULAR_RADIUS_DEG whose radiance is L_sun(λ) = E_sun,normal(λ) / Ω_sun, so that its solid
angle integral is exactly the direct-normal irradiance that lights the scene (daylight.py).

How a pixel gets its share: the disc is sampled by N directions uniform in solid angle (a
deterministic sunflower spiral on the spherical cap, each carrying Ω_sun / N), each direction is
projected through the pinhole camera (the pose's camera_to_world and the render's horizontal FOV,
Mitsuba's `perspective` convention) and counted in the pixel it lands in, weighted by the image
area per solid angle 1/cos³θ, unless the ray from the camera toward it hits the scene (a Mitsuba
ray test) or, without a Mitsuba scene, unless its pixel is not sky. A pixel's coverage is the
fraction of its image-plane area the visible disc covers, which is what a box-filtered render
of the disc would record; the added radiance is coverage × L_sun as the film reports it.
Sampling the disc rather than the pixels keeps energy to ≪ 1 % whether the disc spans one pixel
(wide FOV) or hundreds (a telephoto): N grows with the disc's footprint in pixels.

Not modelled: limb darkening (the disc is uniform; its integral is right), the sky radiance the
disc hides (≈ 10⁻⁶ of the sun's), refraction flattening near the horizon, and the full lens
model's bent rays (render_city_scene notes that the disc is not composited there).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.errors import InvalidValueError
from workbench.render.daylight import sun_angles, sun_direction, sun_irradiance
from workbench.render.film import FilmSRFs
from workbench.render.params import DaylightParams
from workbench.render.scene_builder import camera_to_world
from workbench.scene.city.types import CameraPose
from workbench.units import energy_to_photons

SUN_ANGULAR_RADIUS_DEG = 0.2666          # mean apparent radius of the solar disc (32.0' diameter)
MIN_DISC_SAMPLES = 4096
SAMPLES_PER_PIXEL = 256                  # disc samples per pixel of the disc's footprint
MAX_DISC_SAMPLES = 1 << 21
_GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


def sun_solid_angle_sr(radius_deg: float = SUN_ANGULAR_RADIUS_DEG) -> float:
    """Solid angle (sr) of a disc of angular radius `radius_deg`: 2π(1 − cos r)."""
    if not 0 < radius_deg < 90:
        raise InvalidValueError(f"radius_deg must be in (0, 90), got {radius_deg}")
    return float(2 * np.pi * (1 - np.cos(np.radians(radius_deg))))


def sun_radiance_photons(wavelengths_nm: np.ndarray, daylight: DaylightParams) -> np.ndarray:
    """Radiance of the (uniform) solar disc, photons/s/sr/m²/nm: sun_scale × E_sun,normal / Ω_sun."""
    el, _ = sun_angles(daylight)
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    e_w = daylight.sun_scale * sun_irradiance(wl, el, daylight.turbidity)      # W/m²/nm
    return energy_to_photons(e_w, wl) / sun_solid_angle_sr()


def sun_film_radiance(film: FilmSRFs, daylight: DaylightParams) -> np.ndarray:
    """The disc's radiance as the film reports it (on film.output_wavelengths_nm): the photon
    integral ∫ L_sun s_k dλ of every response (1 nm grid plus the responses' knots), through the
    film's reconstruction, clipped at 0 like channels_to_radiance."""
    knots = film.wavelengths_nm
    wl = np.union1d(knots, np.arange(np.ceil(knots[0]), knots[-1], 1.0))
    resp = np.stack([np.interp(wl, knots, r) for r in film.responses])
    integrals = np.trapezoid(resp * sun_radiance_photons(wl, daylight), wl, axis=1)
    return np.maximum(film.reconstruction @ integrals, 0.0)


def disc_directions(centre: np.ndarray, count: int, radius_deg: float = SUN_ANGULAR_RADIUS_DEG) -> np.ndarray:
    """`count` unit vectors (count×3) uniform in solid angle over the cap of angular radius
    `radius_deg` about `centre` (a sunflower spiral: deterministic, low discrepancy)."""
    if count < 1:
        raise InvalidValueError(f"count must be ≥ 1, got {count}")
    c = np.asarray(centre, dtype=np.float64)
    c = c / np.linalg.norm(c)
    i = np.arange(count, dtype=np.float64)
    cos_t = 1 - (1 - np.cos(np.radians(radius_deg))) * (i + 0.5) / count
    sin_t = np.sqrt(np.maximum(1 - cos_t ** 2, 0.0))
    phi = i * _GOLDEN_ANGLE
    a = np.array([1.0, 0.0, 0.0]) if abs(c[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(c, a)
    u /= np.linalg.norm(u)
    v = np.cross(c, u)
    return (cos_t[:, None] * c + (sin_t * np.cos(phi))[:, None] * u + (sin_t * np.sin(phi))[:, None] * v)


def pinhole_frame(pose: CameraPose) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(forward, image_right, image_down) world unit vectors of the pinhole camera Mitsuba's
    look_at builds from camera_to_world(pose): columns grow to the right, rows downward."""
    origin, target, up = camera_to_world(pose)
    fwd = (target - origin) / np.linalg.norm(target - origin)
    left = np.cross(up, fwd)
    left /= np.linalg.norm(left)
    return fwd, -left, -np.cross(fwd, left)


def project_directions(pose: CameraPose, fov_deg: float, width: int, height: int,
                       directions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Image position (column, row in pixels, row 0 at the top) of world directions seen through
    the pinhole, and the cosine of their angle to the optical axis (≤ 0: behind the camera)."""
    if not 0 < fov_deg < 180:
        raise InvalidValueError(f"fov_deg must be in (0, 180), got {fov_deg}")
    fwd, right, down = pinhole_frame(pose)
    d = np.asarray(directions, dtype=np.float64)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    z = d @ fwd
    safe = np.where(z > 0, z, 1.0)
    tan_x = np.tan(np.radians(fov_deg) / 2)
    tan_y = tan_x * height / width
    col = ((d @ right) / safe / tan_x + 1) * width / 2
    row = ((d @ down) / safe / tan_y + 1) * height / 2
    return col, row, z


def _ray_transmittance(mi_scene, origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Fraction of the direct sun reaching the camera along each direction (JIT variants): 0 where
    the ray hits the scene, e^{−σt} where it leaves the fog box at distance t (fog.py), else 1."""
    import drjit as dr
    import mitsuba as mi

    from workbench.render.fog import FOG_BOX_ID

    if not mi.variant().startswith(("llvm", "cuda")):
        raise InvalidValueError(f"sun disc ray tests need a JIT Mitsuba variant (llvm/cuda), got {mi.variant()}; "
                         "pass sky_mask instead")
    d = np.ascontiguousarray(directions, dtype=np.float32)
    ray = mi.Ray3f(mi.Point3f(*(float(v) for v in origin)), mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
    si = mi_scene.ray_intersect(ray)
    shape = dr.reinterpret_array(mi.UInt32, si.shape)
    dr.eval(si.t, shape)
    hit = np.array(si.is_valid(), dtype=bool).reshape(len(d))
    out = np.where(hit, 0.0, 1.0)
    for box in (s for s in mi_scene.shapes() if s.id() == FOG_BOX_ID):
        sigma = float(mi.traverse(box.interior_medium())["sigma_t.value.value"][0])
        through = hit & (np.array(shape) == int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(box))[0]))
        out[through] = np.exp(-sigma * np.array(si.t, dtype=np.float64)[through])
    return out


def sun_disc_coverage(pose: CameraPose, fov_deg: float, width: int, height: int,
                      daylight: DaylightParams, *, mi_scene=None, sky_mask: np.ndarray | None = None
                      ) -> np.ndarray:
    """H×W fraction of each pixel's image-plane area covered by the visible sun disc (0…1; fully
    covered pixels scatter by a few % about 1 from the disc sampling, sums are exact to ≪ 1 %).

    Visibility: a Mitsuba ray cast from the camera toward each disc sample when `mi_scene` is
    given (sub-pixel accurate at object edges; in fog the disc is dimmed by e^{−σt} over the
    path t through the fog box), else `sky_mask` (H×W bool, True = sky: the
    pixel-centre label). One of the two is required; mi_scene wins when both are given."""
    if not 0 < fov_deg < 180:
        raise InvalidValueError(f"fov_deg must be in (0, 180), got {fov_deg}")
    if width < 1 or height < 1:
        raise InvalidValueError(f"width and height must be ≥ 1, got {width}×{height}")
    if mi_scene is None and sky_mask is None:
        raise InvalidValueError("sun_disc_coverage needs mi_scene (ray tests) or sky_mask (H×W bool)")
    if sky_mask is not None and np.shape(sky_mask) != (height, width):
        raise InvalidValueError(f"sky_mask must be {height}×{width}, got {np.shape(sky_mask)}")
    coverage = np.zeros((height, width), dtype=np.float64)
    sun = sun_direction(*sun_angles(daylight))
    fwd, _, _ = pinhole_frame(pose)
    tan_x = np.tan(np.radians(fov_deg) / 2)
    tan_y = tan_x * height / width
    half_diag = np.arctan(np.hypot(tan_x, tan_y))
    if np.arccos(np.clip(sun @ fwd, -1, 1)) > half_diag + np.radians(2 * SUN_ANGULAR_RADIUS_DEG):
        return coverage                                       # the disc is nowhere near the view
    omega = sun_solid_angle_sr()
    pixel_area = (2 * tan_x / width) ** 2                     # image plane at unit distance
    count = int(np.clip(np.ceil(SAMPLES_PER_PIXEL * max(omega / pixel_area, 1.0)),
                        MIN_DISC_SAMPLES, MAX_DISC_SAMPLES))
    dirs = disc_directions(sun, count)
    col, row, z = project_directions(pose, fov_deg, width, height, dirs)
    inside = (z > 0) & (col >= 0) & (col < width) & (row >= 0) & (row < height)
    if not inside.any():
        return coverage
    dirs, z = dirs[inside], z[inside]
    c, r = np.floor(col[inside]).astype(np.int64), np.floor(row[inside]).astype(np.int64)
    if mi_scene is not None:
        trans = _ray_transmittance(mi_scene, camera_to_world(pose)[0], dirs)
    else:
        trans = np.asarray(sky_mask, dtype=np.float64)[r, c]
    seen = trans > 0
    # image area per sample / pixel area, times the direct beam's transmittance (fog)
    weight = (omega / count) / z[seen] ** 3 / pixel_area * trans[seen]
    np.add.at(coverage, (r[seen], c[seen]), weight)
    return coverage


@dataclass
class SunDisc:
    """The visible sun of one view: per-pixel coverage (H×W, 0…1) and the disc's radiance as the
    film reports it (on film.output_wavelengths_nm, photons/s/sr/m²/nm)."""

    coverage: np.ndarray
    film_radiance: np.ndarray
    meta: dict

    def add_to(self, radiance_photons: np.ndarray) -> np.ndarray:
        """radiance + coverage × disc radiance, float32 (the input is not modified)."""
        rad = np.asarray(radiance_photons)
        if rad.shape != (*self.coverage.shape, self.film_radiance.size):
            raise InvalidValueError(f"radiance must be {self.coverage.shape[0]}×{self.coverage.shape[1]}×"
                             f"{self.film_radiance.size} (the film's outputs), got {rad.shape}")
        hit = self.coverage > 0
        if not hit.any():
            return rad.astype(np.float32, copy=False)
        out = rad.astype(np.float64)
        out[hit] += self.coverage[hit][:, None] * self.film_radiance
        if not np.all(np.isfinite(out[hit])) or out[hit].max() > np.finfo(np.float32).max:
            raise InvalidValueError("sun disc: composited radiance is not finite in float32 (sun_scale too large?)")
        return out.astype(np.float32)


def sun_disc(film: FilmSRFs, pose: CameraPose, fov_deg: float, width: int, height: int,
             daylight: DaylightParams, *, mi_scene=None, sky_mask: np.ndarray | None = None) -> SunDisc:
    """The sun disc of a pinhole view (sun_disc_coverage, sun_film_radiance); coverage 0 when
    daylight.sun_visible is False, sun_scale is 0 or the sky is overcast."""
    if not daylight.sun_visible or daylight.sun_scale == 0 or daylight.sky_model == "overcast":
        return SunDisc(np.zeros((height, width)), np.zeros(film.output_wavelengths_nm.size),
                       {"status": "off"})
    coverage = sun_disc_coverage(pose, fov_deg, width, height, daylight, mi_scene=mi_scene, sky_mask=sky_mask)
    meta = {"status": "composited", "pixels": int(np.count_nonzero(coverage)),
            "coverage_sum": float(coverage.sum()), "angular_radius_deg": SUN_ANGULAR_RADIUS_DEG}
    return SunDisc(coverage, sun_film_radiance(film, daylight), meta)

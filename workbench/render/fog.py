"""Fog and haze over the city (FogParams): a homogeneous medium ('volumetric') or Koschmieder's law.

Extinction σ = 3.912 / V from the meteorological visibility V (Koschmieder: the distance at
which a black object's contrast against the horizon sky falls to 2 %, e^{−σV} = 0.02), constant
over wavelength (fog droplets ≫ λ). The medium fills a box from 1 m below the ground to
`height_m`, 50 m beyond the city's extent; the box has a null BSDF (an index-matched boundary),
the camera starts inside it and every city mesh has it as its exterior medium, so that light
is attenuated and scattered on every segment; Mitsuba's `volpath` integrator renders it.
Rays that leave the box see the sky unattenuated beyond it. The label pass and the depth map
treat the box as background (FOG_BOX_ID has no label); the composited solar disc is dimmed by
e^{−σt} over its path t through the box (sun_disc.py).

FogParams.model 'koschmieder' (render/koschmieder.py) renders the city in clear air and fogs each
pixel afterwards by Koschmieder's law with a measured source function.
"""
from __future__ import annotations

import numpy as np

from workbench.errors import InvalidValueError

KOSCHMIEDER = 3.912          # −ln(0.02)
FOG_BOX_ID = "fog_box"
FOG_MEDIUM_ID = "fog"


def extinction_per_m(visibility_m: float) -> float:
    """Extinction coefficient σ (1/m) for meteorological visibility V: 3.912 / V."""
    if not visibility_m > 0:
        raise InvalidValueError(f"visibility_m must be > 0, got {visibility_m}")
    return KOSCHMIEDER / float(visibility_m)


def fog_medium(fog):
    """The loaded Mitsuba homogeneous medium of FogParams `fog`."""
    import mitsuba as mi

    return mi.load_dict({"type": "homogeneous", "sigma_t": extinction_per_m(fog.visibility_m),
                         "albedo": float(fog.albedo), "phase": {"type": "hg", "g": float(fog.phase_g)}})


def fog_box(medium, extent_m, height_m: float, margin_m: float = 50.0) -> dict:
    """The medium's boundary: a null-BSDF cube over extent_m (xmin, ymin, xmax, ymax), z −1…height_m."""
    import mitsuba as mi

    lo, hi = box_bounds_m(extent_m, height_m, margin_m)
    c, h = (lo + hi) / 2, (hi - lo) / 2
    to_world = mi.ScalarTransform4f().translate(c.tolist()) @ mi.ScalarTransform4f().scale(h.tolist())
    return {"type": "cube", "to_world": to_world, "bsdf": {"type": "null"}, "interior": medium}


def check_camera_inside(origin_m, extent_m, height_m: float, margin_m: float = 50.0) -> None:
    """Refuse a camera outside the fog box (the medium would then not be on its rays)."""
    x0, y0, x1, y1 = extent_m
    x, y, z = (float(v) for v in origin_m)
    if not (x0 - margin_m < x < x1 + margin_m and y0 - margin_m < y < y1 + margin_m and -1 < z < height_m):
        raise InvalidValueError(f"camera at ({x:.1f}, {y:.1f}, {z:.1f}) m is outside the fog layer "
                         f"(height_m = {height_m}); raise fog.height_m")


def box_bounds_m(extent_m, height_m: float, margin_m: float = 50.0) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) corners (m) of the fog layer box over extent_m (xmin, ymin, xmax, ymax)."""
    x0, y0, x1, y1 = (float(v) for v in extent_m)
    return np.array([x0 - margin_m, y0 - margin_m, -1.0]), np.array([x1 + margin_m, y1 + margin_m, float(height_m)])


def exit_distance_m(origin_m, directions, lo, hi) -> np.ndarray:
    """Distance (m) along each unit direction (…×3) from origin_m, inside the box [lo, hi], to its boundary."""
    o = np.asarray(origin_m, dtype=np.float64)
    d = np.asarray(directions, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(d > 0, (np.asarray(hi) - o) / d, np.where(d < 0, (np.asarray(lo) - o) / d, np.inf))
    return np.maximum(t.min(axis=-1), 0.0)


def pixel_directions(mi_scene) -> tuple[np.ndarray, np.ndarray]:
    """(camera centre (3,), H×W×3 unit directions) of the pixel-centre rays of the scene's sensor."""
    import drjit as dr
    import mitsuba as mi

    sensor = mi_scene.sensors()[0]
    w, h = (int(v) for v in sensor.film().crop_size())
    idx = dr.arange(mi.UInt32, w * h)
    pos = mi.Point2f((mi.Float(idx % w) + 0.5) / w, (mi.Float(idx // w) + 0.5) / h)
    ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
    d = np.stack([np.array(ray.d.x), np.array(ray.d.y), np.array(ray.d.z)], axis=-1).astype(np.float64)
    centre = np.array(sensor.world_transform().translation(), dtype=np.float64).ravel()
    return centre, d.reshape(h, w, 3)


def transmittance(sigma_per_m: float, path_m) -> np.ndarray:
    """Beer–Lambert transmittance e^{−σd} of a homogeneous medium over path_m."""
    return np.exp(-float(sigma_per_m) * np.asarray(path_m, dtype=np.float64))


def sun_through_layer(daylight, fog):
    """Daylight whose direct sun is dimmed to what reaches the ground through the layer:
    sun_scale × e^{−σ H / sin(elevation)} (the Koschmieder model's object lighting)."""
    from workbench.render.daylight import sun_angles

    el, _ = sun_angles(daylight)
    path_m = float(fog.height_m) / np.sin(np.radians(el))
    return daylight.updated(sun_scale=daylight.sun_scale * float(transmittance(extinction_per_m(fog.visibility_m),
                                                                               path_m)))

"""Fog and haze: a homogeneous participating medium in a box over the city (FogParams).

Extinction σ = 3.912 / V from the meteorological visibility V (Koschmieder: the distance at
which a black object's contrast against the horizon sky falls to 2 %, e^{−σV} = 0.02), constant
over wavelength (fog droplets ≫ λ). The medium fills a box from 1 m below the ground to
`height_m`, 50 m beyond the city's extent; the box has a null BSDF (an index-matched boundary),
the camera starts inside it and every city mesh has it as its exterior medium, so that light
is attenuated and scattered on every segment; Mitsuba's `volpath` integrator renders it.
Rays that leave the box see the sky unattenuated beyond it. The label pass and the depth map
treat the box as background (FOG_BOX_ID has no label); the composited solar disc is dimmed by
e^{−σt} over its path t through the box (sun_disc.py).
"""
from __future__ import annotations

import numpy as np

KOSCHMIEDER = 3.912          # −ln(0.02)
FOG_BOX_ID = "fog_box"
FOG_MEDIUM_ID = "fog"


def extinction_per_m(visibility_m: float) -> float:
    """Extinction coefficient σ (1/m) for meteorological visibility V: 3.912 / V."""
    if not visibility_m > 0:
        raise ValueError(f"visibility_m must be > 0, got {visibility_m}")
    return KOSCHMIEDER / float(visibility_m)


def fog_medium(fog):
    """The loaded Mitsuba homogeneous medium of FogParams `fog`."""
    import mitsuba as mi

    return mi.load_dict({"type": "homogeneous", "sigma_t": extinction_per_m(fog.visibility_m),
                         "albedo": float(fog.albedo), "phase": {"type": "hg", "g": float(fog.phase_g)}})


def fog_box(medium, extent_m, height_m: float, margin_m: float = 50.0) -> dict:
    """The medium's boundary: a null-BSDF cube over extent_m (xmin, ymin, xmax, ymax), z −1…height_m."""
    import mitsuba as mi

    x0, y0, x1, y1 = (float(v) for v in extent_m)
    lo = np.array([x0 - margin_m, y0 - margin_m, -1.0])
    hi = np.array([x1 + margin_m, y1 + margin_m, float(height_m)])
    c, h = (lo + hi) / 2, (hi - lo) / 2
    to_world = mi.ScalarTransform4f().translate(c.tolist()) @ mi.ScalarTransform4f().scale(h.tolist())
    return {"type": "cube", "to_world": to_world, "bsdf": {"type": "null"}, "interior": medium}


def check_camera_inside(origin_m, extent_m, height_m: float, margin_m: float = 50.0) -> None:
    """Refuse a camera outside the fog box (the medium would then not be on its rays)."""
    x0, y0, x1, y1 = extent_m
    x, y, z = (float(v) for v in origin_m)
    if not (x0 - margin_m < x < x1 + margin_m and y0 - margin_m < y < y1 + margin_m and -1 < z < height_m):
        raise ValueError(f"camera at ({x:.1f}, {y:.1f}, {z:.1f}) m is outside the fog layer "
                         f"(height_m = {height_m}); raise fog.height_m")

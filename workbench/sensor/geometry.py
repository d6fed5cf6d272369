"""Field of view ↔ focal length for a sensor's pixel array (pinhole / thin lens at infinity)."""
from __future__ import annotations

import math

from workbench.sensor.params import SensorParams


def sensor_fov_deg(params: SensorParams, focal_length_m: float) -> float:
    """Horizontal field of view (deg) = 2·atan(width / 2f) of the pixel array behind a lens."""
    if not focal_length_m > 0:
        raise ValueError(f"focal_length_m must be > 0, got {focal_length_m}")
    width_m = params.sensor_size_m[1]
    return math.degrees(2.0 * math.atan(width_m / (2.0 * focal_length_m)))


def focal_length_for_fov(params: SensorParams, fov_deg: float) -> float:
    """Focal length (m) that gives the pixel array a horizontal field of view of fov_deg."""
    if not 0.0 < fov_deg < 180.0:
        raise ValueError(f"fov_deg must lie in (0, 180), got {fov_deg}")
    width_m = params.sensor_size_m[1]
    return width_m / (2.0 * math.tan(math.radians(fov_deg) / 2.0))

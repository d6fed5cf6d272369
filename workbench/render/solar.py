"""Solar position: the sun's elevation and compass azimuth at a local solar time, latitude and day."""
from __future__ import annotations

import numpy as np


def solar_position(time_of_day_h: float, latitude_deg: float, day_of_year: int) -> tuple[float, float]:
    """Sun (elevation_deg, compass azimuth_deg) at local solar time (Cooper's declination)."""
    decl = np.radians(23.44) * np.sin(2 * np.pi * (284 + day_of_year) / 365.0)
    hour = np.radians(15.0 * (time_of_day_h - 12.0))
    lat = np.radians(latitude_deg)
    sin_el = np.sin(lat) * np.sin(decl) + np.cos(lat) * np.cos(decl) * np.cos(hour)
    el = np.arcsin(np.clip(sin_el, -1, 1))
    # azimuth from north, clockwise: east component and north component of the sun direction
    east = -np.cos(decl) * np.sin(hour)
    north = np.sin(decl) * np.cos(lat) - np.cos(decl) * np.sin(lat) * np.cos(hour)
    az = np.degrees(np.arctan2(east, north)) % 360.0
    return float(np.degrees(el)), float(az)

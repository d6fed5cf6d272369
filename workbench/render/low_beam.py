"""Low-beam head-light: a luminous-intensity pattern that meets the SAE J1383 low-beam test points,
and the projection texture that gives it to a Mitsuba `spot` (and to render/lamp_set.py).

Angles are those of a head-lamp goniometer in the aimed lamp's frame: h (deg) to the right of the
vertical plane through the lamp's axis (azimuth), v (deg) above the horizontal (elevation). Right-hand
traffic (the city's): the cut-off is lowest on the left, toward oncoming drivers.

I(h, v) = I_max · P(v) · H(h) · S(v − c(h)) + F(h, v) · (1 − S(v − c(h))), with

- the cut-off c(h) at CUTOFF_LEFT_DEG on the left, rising at 15° right of the vertical (the
  "kick-up") to CUTOFF_RIGHT_DEG, and S(x) = 1 / (1 + 10^(k x)) its step: k = CUTOFF_K per degree
  gives a log-gradient of 0.15 per 0.1° at the inflection and 0.3 above it, inside the band UN R112 / R149 ask
  of a cut-off (sharpness G 0.13–0.40);
- P(v) = 1 from the cut-off down to HOT_SPOT_V_DEG, then the vertical profile of a beam that keeps the
  road's illuminance about even (isetauto's "Generic Headlamp Light Distribution", relative candela
  at 1°–10° down, normalised at 1.5° down; past 10° down the power law through its 5° and 10°
  values), so the road just ahead of the car gets tens of lux, not hundreds;
- H(h) = 0.7 × an asymmetric Gaussian about the hot spot at HOT_SPOT_H_DEG right (σ 3.2° to the
  left, 5° to the right) + 0.3 × a broad one (σ 20°) that lights the roadside;
- F(h, v) the light above the cut-off (overhead signs: SAE asks ≥ 125 cd at 2U 4L–4R, ≤ 125 cd at
  10U–90U): FLOOR_CD × exp(−(h/15°)²/2), falling linearly to a quarter of it from 4U to 10U.

The shape parameters are design choices, not measured data (photometric matrices of production
lamps, e.g. UMTRI-93-11, were not available): each is chosen so that the pattern meets every
J1383 low-beam requirement (J1383_LOW_BEAM, tested), with I_max at the 1.5D 2R hot spot. The
table is SAE J1383's low-beam specification as quoted in a published patent application; FMVSS 108
holds the same test points. Its luminous flux at I_max 20,000 cd is 384 lm (low_beam_flux_lm).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from workbench.errors import InvalidValueError

CUTOFF_LEFT_DEG = -0.75       # cut-off on the left (deg, up +)
CUTOFF_RIGHT_DEG = -0.2       # cut-off on the right, after the 15° kick-up
KICK_UP_SLOPE = np.tan(np.radians(15.0))
CUTOFF_K = 3.0                # S(x) = 1 / (1 + 10^(k x)), x in degrees above the cut-off
HOT_SPOT_V_DEG = -1.5
HOT_SPOT_H_DEG = 2.0
SIGMA_LEFT_DEG, SIGMA_RIGHT_DEG, SIGMA_WIDE_DEG = 3.2, 5.0, 20.0
WIDE_SHARE = 0.3
FLOOR_CD = 250.0              # light above the cut-off at I_max 20,000 cd (scales with I_max)
FLOOR_REFERENCE_CD = 20000.0
TEXTURE_CUTOFF_DEG = 60.0     # the spot's cone: the texture spans tan(60°) each way
TEXTURE_SIZE = (2048, 1024)   # texels (rows: up, columns: across)

# isetauto @headlamp "Generic Headlamp Light Distribution": degrees down → % of the 1°-down value
_PROFILE_DOWN_DEG = np.arange(1.0, 10.01, 0.5)
_PROFILE_PERCENT = np.array([100.0, 55.0, 33.0, 21.0, 14.1, 10.05, 7.5, 5.75, 4.55, 3.65, 3.0, 2.5,
                             2.1, 1.8, 1.55, 1.34, 1.18, 1.05, 0.95])
_TAIL_EXPONENT = np.log(4.55 / 0.95) / np.log(10.0 / 5.0)

# SAE J1383 low beam, per lamp: (name, v range deg (up +), h range deg (right +), min cd, max cd);
# a range is checked over its whole extent, "to L" / "to R" as far as 45°
J1383_LOW_BEAM = (
    ("10U-90U, 45L-45R", (10.0, 90.0), (-45.0, 45.0), None, 125.0),
    ("H-4U, 8L-8R", (0.0, 4.0), (-8.0, 8.0), 64.0, None),
    ("H-2U, 4L-4R", (0.0, 2.0), (-4.0, 4.0), 125.0, None),
    ("1U, 1.5L to L", (1.0, 1.0), (-45.0, -1.5), None, 700.0),
    ("0.5U, 1.5L to L", (0.5, 0.5), (-45.0, -1.5), None, 1000.0),
    ("0.5D, 1.5L to L", (-0.5, -0.5), (-45.0, -1.5), None, 3000.0),
    ("1.5U, 1R to R", (1.5, 1.5), (1.0, 45.0), None, 1400.0),
    ("0.5U, 1R-3R", (0.5, 0.5), (1.0, 3.0), None, 2700.0),
    ("0.5D, 1.5R", (-0.5, -0.5), (1.5, 1.5), 8000.0, 20000.0),
    ("1D, 6L", (-1.0, -1.0), (-6.0, -6.0), 750.0, None),
    ("1.5D, 2R", (-1.5, -1.5), (2.0, 2.0), 15000.0, None),
    ("1.5D, 9L", (-1.5, -1.5), (-9.0, -9.0), 750.0, None),
    ("1.5D, 9R", (-1.5, -1.5), (9.0, 9.0), 750.0, None),
    ("2D, 15L", (-2.0, -2.0), (-15.0, -15.0), 700.0, None),
    ("2D, 15R", (-2.0, -2.0), (15.0, 15.0), 700.0, None),
    ("4D, 4R", (-4.0, -4.0), (4.0, 4.0), None, 8000.0),
)
J1383_PEAK_CD = 20000.0       # the table's I_max: 0.5D 1.5R at most 20,000 cd


def cutoff_deg(h_deg):
    """The cut-off's elevation (deg) at azimuth h_deg (right +)."""
    h = np.asarray(h_deg, dtype=np.float64)
    return np.clip(CUTOFF_LEFT_DEG + KICK_UP_SLOPE * h, CUTOFF_LEFT_DEG, CUTOFF_RIGHT_DEG)


def _vertical(v_deg):
    down = np.maximum(-np.asarray(v_deg, dtype=np.float64), -HOT_SPOT_V_DEG)
    rel = np.interp(down, _PROFILE_DOWN_DEG, _PROFILE_PERCENT)
    tail = _PROFILE_PERCENT[-1] * (10.0 / np.maximum(down, 10.0)) ** _TAIL_EXPONENT
    return np.where(down > 10.0, tail, rel) / np.interp(-HOT_SPOT_V_DEG, _PROFILE_DOWN_DEG, _PROFILE_PERCENT)


def _horizontal(h_deg):
    h = np.asarray(h_deg, dtype=np.float64) - HOT_SPOT_H_DEG
    core = np.exp(-0.5 * (h / np.where(h < 0, SIGMA_LEFT_DEG, SIGMA_RIGHT_DEG)) ** 2)
    wide = np.exp(-0.5 * ((h + HOT_SPOT_H_DEG) / SIGMA_WIDE_DEG) ** 2)
    return (1.0 - WIDE_SHARE) * core + WIDE_SHARE * wide


def low_beam_cd(h_deg, v_deg, peak_cd: float = J1383_PEAK_CD) -> np.ndarray:
    """Luminous intensity (cd) of the low beam toward (h_deg right, v_deg up), its hot spot peak_cd."""
    if not peak_cd > 0:
        raise InvalidValueError(f"low beam: peak_cd must be > 0, got {peak_cd}")
    h, v = np.broadcast_arrays(np.asarray(h_deg, dtype=np.float64), np.asarray(v_deg, dtype=np.float64))
    step = 1.0 / (1.0 + 10.0 ** np.clip(CUTOFF_K * (v - cutoff_deg(h)), -30.0, 30.0))
    floor = (FLOOR_CD / FLOOR_REFERENCE_CD) * np.exp(-0.5 * (h / 15.0) ** 2) * (
        0.25 + 0.75 * np.clip((10.0 - v) / 6.0, 0.0, 1.0))
    beam = _vertical(v) * _horizontal(h) / _horizontal(HOT_SPOT_H_DEG)
    return peak_cd * (beam * step + floor * (1.0 - step))


def direction_angles_deg(x_left, y_up, z_forward) -> tuple[np.ndarray, np.ndarray]:
    """(h right, v up) in degrees of directions in a spot's local frame (x left, y up, z along the
    axis: Mitsuba's look_at with up +Z)."""
    x, y, z = (np.asarray(a, dtype=np.float64) for a in (x_left, y_up, z_forward))
    return np.degrees(np.arctan2(-x, z)), np.degrees(np.arctan2(y, np.hypot(x, z)))


def texture_array(size=TEXTURE_SIZE, cutoff: float = TEXTURE_CUTOFF_DEG) -> np.ndarray:
    """The pattern over a spot's projection texture (rows × columns × 1, float32, max 1): texel
    (i, j) is the direction (x, y, 1) with x = (2u − 1) tan(cutoff), y = (2v − 1) tan(cutoff), u =
    (j + ½)/columns, v = (i + ½)/rows (as Mitsuba's spot maps a direction to uv: row 0 is down,
    column 0 is the lamp's right)."""
    rows, cols = size
    f = np.tan(np.radians(cutoff))
    y = (2.0 * (np.arange(rows) + 0.5) / rows - 1.0) * f
    x = (2.0 * (np.arange(cols) + 0.5) / cols - 1.0) * f
    h, v = direction_angles_deg(x[None, :], y[:, None], 1.0)
    cd = low_beam_cd(h, v, 1.0)
    return (cd / cd.max()).astype(np.float32)[..., None]


def low_beam_flux_lm(peak_cd: float = J1383_PEAK_CD) -> float:
    """Luminous flux (lm) of the pattern within the spot's cone (proportional to peak_cd)."""
    if not peak_cd > 0:
        raise InvalidValueError(f"low beam: peak_cd must be > 0, got {peak_cd}")
    return peak_cd * _flux_per_cd()


@lru_cache(maxsize=1)
def _flux_per_cd(step_deg: float = 0.25) -> float:
    """∫ I dΩ of the pattern at peak 1 cd over the cone, on a grid of step_deg in (h, v)."""
    h = np.radians(np.arange(-90.0 + step_deg / 2, 90.0, step_deg))
    hh, vv = np.meshgrid(h, h)
    forward = np.cos(vv) * np.cos(hh)
    inside = forward > np.cos(np.radians(TEXTURE_CUTOFF_DEG))
    cd = low_beam_cd(np.degrees(hh), np.degrees(vv), 1.0)
    return float((cd * inside * np.cos(vv)).sum() * np.radians(step_deg) ** 2)


@lru_cache(maxsize=4)
def _texture_for(variant: str):
    import mitsuba as mi

    return mi.load_dict({"type": "bitmap", "bitmap": mi.Bitmap(texture_array()), "raw": True,
                         "filter_type": "bilinear", "wrap_mode": "clamp"})


def low_beam_texture():
    """The pattern as a loaded Mitsuba bitmap texture for the current variant (one per process,
    shared by every head-light's spot)."""
    import mitsuba as mi

    return _texture_for(mi.variant())

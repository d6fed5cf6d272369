"""Clear-sky daylight: solar position, a spectral sun attenuated by the atmosphere, a uniform sky.

Physics (facts from the literature, coded here):
- Extraterrestrial sun: a 5778 K blackbody scaled to the solar constant 1361 W/m² (TSIS-1).
  Smooth: it lacks the Fraunhofer lines of the measured spectrum (a few % locally).
- Direct beam (Bird & Riordan 1986, SPCTRAL2): T = exp(−m (τ_R + τ_a)) with the sea-level
  Rayleigh optical depth of Bodhaine et al. 1999 (colour-science) and Ångström aerosol
  τ_a = β λ^−α, α = 1.3, β = 0.04608 T_L − 0.04586 from the turbidity T_L (Preetham et al. 1999);
  air mass m from Kasten & Young (1989).
- Sky: SPCTRAL2's diffuse Rayleigh + aerosol terms (single-scattering albedo 0.945·exp(−0.095
  ln²(λ/0.4)), asymmetry 0.65), spread as a uniform sky radiance L = E_diffuse / π.
- Not modelled: ozone, O₂ (760 nm) and water-vapour (940 nm) absorption, ground-reflected
  sky light, twilight (sky brightness gradients and overcast: sky.py) (the sun must be above the horizon).
Spectra are energy units: irradiance W/m²/nm, radiance W/m²/sr/nm.
"""
from __future__ import annotations

import numpy as np

from workbench.errors import InvalidValueError
from workbench.render.params import DaylightParams
from workbench.render.solar import solar_position
from workbench.spectra import blackbody_spd

SOLAR_CONSTANT_W_M2 = 1361.0
SUN_TEMPERATURE_K = 5778.0
ANGSTROM_ALPHA = 1.3
DAYLIGHT_WAVELENGTHS_NM = np.arange(300.0, 1101.0, 5.0)


def sun_angles(daylight: DaylightParams) -> tuple[float, float]:
    """(elevation_deg, azimuth_deg) from the parameters; refuses a sun below the horizon."""
    if daylight.time_of_day_h is None:
        return daylight.sun_elevation_deg, daylight.sun_azimuth_deg
    el, az = solar_position(daylight.time_of_day_h, daylight.latitude_deg, daylight.day_of_year)
    if el <= 0.5:
        raise InvalidValueError(f"time_of_day_h={daylight.time_of_day_h} puts the sun at {el:.1f}° "
                         f"elevation (latitude {daylight.latitude_deg}°, day {daylight.day_of_year});"
                         " daylight needs the sun above the horizon (> 0.5°)")
    return el, az


def sun_direction(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """Unit vector from the scene toward the sun (Z up, +X east, +Y north)."""
    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    return np.array([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])


def extraterrestrial_irradiance(wavelengths_nm: np.ndarray) -> np.ndarray:
    """Solar spectral irradiance above the atmosphere (W/m²/nm), ∫ = 1361 W/m²."""
    sigma_T4 = 5.670374419e-8 * SUN_TEMPERATURE_K ** 4          # W/m² at the sun's surface
    # π B(λ) is the sun's exitance; scale by the solid-angle factor that gives the solar constant
    return np.pi * blackbody_spd(SUN_TEMPERATURE_K, wavelengths_nm) * (SOLAR_CONSTANT_W_M2 / sigma_T4)


def air_mass(zenith_deg: float) -> float:
    """Relative optical air mass (Kasten & Young 1989)."""
    return 1.0 / (np.cos(np.radians(zenith_deg)) + 0.50572 * (96.07995 - zenith_deg) ** -1.6364)


def _optical_depths(wavelengths_nm: np.ndarray, turbidity: float) -> tuple[np.ndarray, np.ndarray]:
    import colour

    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    tau_r = colour.phenomena.rayleigh_optical_depth(wl * 1e-7)      # expects centimetres
    lam_um = wl / 1000.0
    beta = 0.04608 * turbidity - 0.04586
    tau_a = beta * lam_um ** -ANGSTROM_ALPHA
    return tau_r, tau_a


def sun_irradiance(wavelengths_nm: np.ndarray, elevation_deg: float, turbidity: float) -> np.ndarray:
    """Direct-normal solar irradiance at the ground (W/m²/nm)."""
    m = air_mass(90.0 - elevation_deg)
    tau_r, tau_a = _optical_depths(wavelengths_nm, turbidity)
    return extraterrestrial_irradiance(wavelengths_nm) * np.exp(-m * (tau_r + tau_a))


def sky_radiance(wavelengths_nm: np.ndarray, elevation_deg: float, turbidity: float) -> np.ndarray:
    """Uniform clear-sky radiance (W/m²/sr/nm) whose horizontal irradiance equals SPCTRAL2's diffuse."""
    zen = 90.0 - elevation_deg
    cos_z = np.cos(np.radians(zen))
    m = air_mass(zen)
    lam_um = np.asarray(wavelengths_nm, dtype=np.float64) / 1000.0
    tau_r, tau_a = _optical_depths(wavelengths_nm, turbidity)
    omega = 0.945 * np.exp(-0.095 * np.log(lam_um / 0.4) ** 2)
    t_r = np.exp(-m * tau_r)
    t_aa = np.exp(-(1 - omega) * tau_a * m)
    t_as = np.exp(-omega * tau_a * m)
    alg = np.log(1 - 0.65)
    afs = alg * (1.459 + alg * (0.1595 + alg * 0.4129))
    bfs = alg * (0.0783 + alg * (-0.3824 - alg * 0.5874))
    f_s = 1 - 0.5 * np.exp((afs + bfs * cos_z) * cos_z)
    e0 = extraterrestrial_irradiance(wavelengths_nm) * cos_z
    rayleigh = e0 * t_aa * (1 - t_r ** 0.95) * 0.5
    aerosol = e0 * t_aa * t_r ** 1.5 * (1 - t_as) * f_s
    return (rayleigh + aerosol) / np.pi

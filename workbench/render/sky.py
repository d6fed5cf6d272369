"""Skies whose radiance varies with direction, spectral over 300–1100 nm (NIR included).

Models (`DaylightParams.sky_model`):
- 'uniform': today's sky, L(λ) = E_d(λ)/π with E_d SPCTRAL2's diffuse horizontal irradiance
  (daylight.sky_radiance).
- 'perez': clear sky. The luminance distribution of Perez et al. (1993) with Preetham et al.'s
  (1999) turbidity fit of the five coefficients for Y,
      F(θ, γ) = (1 + A e^{B / cos θ}) (1 + C e^{D γ} + E cos² γ),
  θ the zenith angle of the view direction, γ its angle to the sun, times SPCTRAL2's diffuse
  spectrum (its Rayleigh term carries the λ⁻⁴ optical depth of Bodhaine et al. into the NIR):
      L(λ, ω) = E_d(λ) F(θ, γ) / ∫_{2π} F cos θ dω,
  so the horizontal irradiance is exactly SPCTRAL2's diffuse E_d(λ), as for the uniform sky.
  The angular shape is the same at every wavelength (Preetham's chromaticity gradients — a bluer
  zenith, a whiter horizon — are not modelled).
- 'overcast': the CIE standard overcast sky L(θ) ∝ (1 + 2 cos θ)/3 (Moon & Spencer 1942), no
  direct sun; its horizontal irradiance is `overcast_transmittance` × the clear-sky global
  horizontal irradiance (direct·sin(elevation) + diffuse) — clouds are nearly grey (droplets ≫ λ);
  their NIR water absorption is not modelled.

Mitsuba's `envmap` goes through RGB and is 0 above 830 nm (research/mitsuba.md), so the sky is a
Python emitter (`SkyEmitter`): spectral via a `spectrum` texture evaluated at the path's
wavelengths, the angular factor in Dr.Jit, directions sampled uniformly over the upper hemisphere.
Below the horizon the perez and overcast skies are black (the ground is there); the uniform
sky stays Mitsuba's `constant` emitter over the whole sphere. Z up, +X east, +Y north.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from workbench.errors import InvalidValueError
from workbench.render.daylight import (DAYLIGHT_WAVELENGTHS_NM, sky_radiance, sun_angles, sun_direction,
                                       sun_irradiance)
from workbench.render.params import DaylightParams

SKY_MODELS = ("uniform", "perez", "overcast")
NEGLIGIBLE_SPECTRUM = 1e-30   # W/m²/(sr·)nm: below it Mitsuba's float32 sampling tables underflow; left out
_QUAD_THETA, _QUAD_PHI = 512, 1024


def perez_coefficients(turbidity: float) -> np.ndarray:
    """(A, B, C, D, E) of the Perez luminance distribution for turbidity T (Preetham et al. 1999)."""
    t = float(turbidity)
    return np.array([0.1787 * t - 1.4630, -0.3554 * t + 0.4275, -0.0227 * t + 5.3251,
                     0.1206 * t - 2.5771, -0.0670 * t + 0.3703])


def perez(cos_theta: np.ndarray, gamma_rad: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
    """Perez factor F(θ, γ) (cos θ clamped to ≥ 0.01 near the horizon, as is customary)."""
    a, b, c, d, e = coeffs
    ct = np.maximum(cos_theta, 0.01)
    return (1 + a * np.exp(b / ct)) * (1 + c * np.exp(d * gamma_rad) + e * np.cos(gamma_rad) ** 2)


def preetham_zenith_luminance_cd_m2(turbidity: float, sun_elevation_deg: float) -> float:
    """Zenith luminance of Preetham et al. (1999), cd/m² (their fit is in kcd/m²)."""
    theta_s = np.radians(90.0 - sun_elevation_deg)
    chi = (4.0 / 9.0 - turbidity / 120.0) * (np.pi - 2 * theta_s)
    return 1000.0 * float((4.0453 * turbidity - 4.9710) * np.tan(chi) - 0.2155 * turbidity + 2.4192)


def _hemisphere_grid():
    th = (np.arange(_QUAD_THETA) + 0.5) * (np.pi / 2) / _QUAD_THETA
    ph = (np.arange(_QUAD_PHI) + 0.5) * (2 * np.pi) / _QUAD_PHI
    t, p = np.meshgrid(th, ph, indexing="ij")
    d = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)
    d_omega = np.sin(t) * (np.pi / 2 / _QUAD_THETA) * (2 * np.pi / _QUAD_PHI)
    return d, d_omega


def angular_factor(daylight: DaylightParams, directions: np.ndarray) -> np.ndarray:
    """Relative sky radiance g(ω) (≥ 0, 0 below the horizon) of the chosen model, normalised so
    that ∫_{2π} g cos θ dω = π: radiance = g(ω) × the uniform-sky-equivalent spectrum."""
    d = np.asarray(directions, dtype=np.float64)
    return _raw_factor(daylight, d) * (np.pi / _normaliser(daylight))


def _raw_factor(daylight: DaylightParams, d: np.ndarray) -> np.ndarray:
    up = d[..., 2] > 0
    if daylight.sky_model == "uniform":
        return np.ones(d.shape[:-1])          # Mitsuba `constant`: the whole sphere
    if daylight.sky_model == "overcast":
        return np.where(up, (1 + 2 * d[..., 2]) / 3, 0.0)
    sun = sun_direction(*sun_angles(daylight))
    gamma = np.arccos(np.clip(d @ sun, -1.0, 1.0))
    return np.where(up, perez(d[..., 2], gamma, perez_coefficients(daylight.turbidity)), 0.0)


def _normaliser(daylight: DaylightParams) -> float:
    """∫_{2π} raw factor × cos θ dω by midpoint quadrature (512 × 1024), cached per sky."""
    el, az = sun_angles(daylight)
    return _normaliser_cached(daylight.sky_model, float(daylight.turbidity), el, az)


@lru_cache(maxsize=64)
def _normaliser_cached(sky_model: str, turbidity: float, elevation_deg: float, azimuth_deg: float) -> float:
    if sky_model == "uniform":
        return np.pi
    day = DaylightParams(sky_model=sky_model, turbidity=turbidity, sun_elevation_deg=elevation_deg,
                         sun_azimuth_deg=azimuth_deg)
    d, d_omega = _hemisphere_grid()
    return float(np.sum(_raw_factor(day, d) * d[..., 2] * d_omega))


def sky_spectrum(daylight: DaylightParams, wavelengths_nm: np.ndarray = DAYLIGHT_WAVELENGTHS_NM) -> np.ndarray:
    """The uniform-sky-equivalent radiance spectrum (W/m²/sr/nm) = horizontal irradiance / π,
    including sky_scale."""
    el, _ = sun_angles(daylight)
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    clear = sky_radiance(wl, el, daylight.turbidity)
    if daylight.sky_model != "overcast":
        return daylight.sky_scale * clear
    global_h = sun_irradiance(wl, el, daylight.turbidity) * np.sin(np.radians(el)) + np.pi * clear
    return daylight.sky_scale * daylight.overcast_transmittance * global_h / np.pi


def sky_radiance_at(daylight: DaylightParams, directions: np.ndarray,
                    wavelengths_nm: np.ndarray = DAYLIGHT_WAVELENGTHS_NM) -> np.ndarray:
    """Sky radiance (W/m²/sr/nm), directions (…×3, unit, Z up) × wavelengths → …×Nλ."""
    return angular_factor(daylight, directions)[..., None] * sky_spectrum(daylight, wavelengths_nm)


_REGISTERED: dict[str, type] = {}


def _emitter_class():
    """The SkyEmitter class of the current Mitsuba variant (Python plugins are per variant)."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant in _REGISTERED:
        return _REGISTERED[variant]

    class SkyEmitter(mi.Emitter):
        """Environment emitter L(λ, ω) = spectrum(λ) × angular factor (see module docstring)."""

        def __init__(self, props, spectrum=None, model="uniform", coeffs=(0, 0, 0, 0, 0),
                     sun=(0, 0, 1), scale=1.0):
            mi.Emitter.__init__(self, props)
            self.m_flags = mi.EmitterFlags.Infinite | mi.EmitterFlags.SpatiallyVarying
            self.spectrum, self.model, self.coeffs = spectrum, model, [float(c) for c in coeffs]
            self.sun, self.scale = [float(s) for s in sun], float(scale)

        def _radiance(self, d, wavelengths, active):
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.wavelengths = wavelengths
            up = active & (d.z > 0)
            if self.model == "overcast":
                g = self.scale * (1 + 2 * d.z) / 3
            else:
                a, b, c, dd, e = self.coeffs
                cos_g = dr.clip(d.x * self.sun[0] + d.y * self.sun[1] + d.z * self.sun[2], -1, 1)
                gamma = dr.acos(cos_g)
                g = self.scale * (1 + a * dr.exp(b / dr.maximum(d.z, 0.01))) * \
                    (1 + c * dr.exp(dd * gamma) + e * cos_g * cos_g)
            return dr.select(up, self.spectrum.eval(si, up) * g, 0.0)

        def eval(self, si, active=True):
            return self._radiance(-si.wi, si.wavelengths, active)

        def sample_direction(self, it, sample, active=True):
            d = mi.warp.square_to_uniform_hemisphere(sample)
            ds = dr.zeros(mi.DirectionSample3f)
            ds.d, ds.p, ds.n = d, it.p + d * 1e7, -d
            ds.dist, ds.delta, ds.time = dr.inf, False, it.time
            ds.pdf = mi.warp.square_to_uniform_hemisphere_pdf(d)
            return ds, self._radiance(d, it.wavelengths, active) / ds.pdf

        def pdf_direction(self, it, ds, active=True):
            return dr.select(active & (ds.d.z > 0), mi.warp.square_to_uniform_hemisphere_pdf(ds.d), 0.0)

        def eval_direction(self, it, ds, active=True):
            return self._radiance(ds.d, it.wavelengths, active)

        def traverse(self, callback):
            pass

        def to_string(self):
            return f"SkyEmitter[{self.model}]"

    _REGISTERED[variant] = SkyEmitter
    return SkyEmitter


def sky_emitter(daylight: DaylightParams):
    """The chosen sky as a Mitsuba emitter (a spectral variant must be set): a `constant` emitter
    dict for 'uniform', a SkyEmitter object otherwise; None when sky_scale is 0 or so small that
    the radiance is negligible (NEGLIGIBLE_SPECTRUM: no image could show it, and Mitsuba refuses it)."""
    import mitsuba as mi

    if daylight.sky_model not in SKY_MODELS:
        raise InvalidValueError(f"sky_model must be one of {SKY_MODELS}, got {daylight.sky_model!r}")
    wl = DAYLIGHT_WAVELENGTHS_NM
    spec = sky_spectrum(daylight, wl)
    if daylight.sky_scale == 0 or not np.max(spec) > NEGLIGIBLE_SPECTRUM:
        return None
    value = list(zip(wl.tolist(), spec.tolist()))
    if daylight.sky_model == "uniform":
        return {"type": "constant", "radiance": {"type": "spectrum", "value": value}}
    texture = mi.load_dict({"type": "spectrum", "value": value})
    scale = np.pi / _normaliser(daylight)
    sun = sun_direction(*sun_angles(daylight)) if daylight.sky_model == "perez" else (0, 0, 1)
    return _emitter_class()(mi.Properties(), texture, daylight.sky_model,
                            perez_coefficients(daylight.turbidity), sun, scale)


def daylight_emitters(daylight: DaylightParams) -> dict:
    """Mitsuba emitters {'sun': directional dict, 'sky': sky_emitter}, spectra over 300–1100 nm.

    An emitter whose scale is 0, or whose spectrum is negligible (NEGLIGIBLE_SPECTRUM), is left out
    (Mitsuba refuses an all-zero spectrum); an overcast sky has no sun."""
    el, az = sun_angles(daylight)
    wl = DAYLIGHT_WAVELENGTHS_NM
    out = {}
    sun = daylight.sun_scale * sun_irradiance(wl, el, daylight.turbidity)
    if np.max(sun) > NEGLIGIBLE_SPECTRUM and daylight.sky_model != "overcast":
        out["sun"] = {"type": "directional", "direction": (-sun_direction(el, az)).tolist(),
                      "irradiance": {"type": "spectrum", "value": list(zip(wl.tolist(), sun.tolist()))}}
    sky = sky_emitter(daylight)
    if sky is not None:
        out["sky"] = sky
    return out

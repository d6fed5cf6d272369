"""Wavelength grids and spectral data, on colour-science.

Every function takes a wavelength vector in nm and returns data sampled on it, so any grid
works (the default is 400–700 nm in 10 nm steps). Data outside a table's range is
extrapolated as constant; tables that end before the grid ends are flagged in the docstring.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from workbench.errors import InvalidValueError
from workbench.units import (
    MAX_LUMINOUS_EFFICACY_LM_W,
    band_widths_nm,
    energy_to_photons,
    photons_to_energy,
)

DEFAULT_WAVELENGTHS_NM = np.arange(400.0, 701.0, 10.0)


def wavelength_grid(start_nm: float = 400.0, stop_nm: float = 700.0, step_nm: float = 10.0) -> np.ndarray:
    """Evenly spaced wavelengths (nm), both ends included."""
    if step_nm <= 0 or stop_nm < start_nm:
        raise InvalidValueError(f"wavelength grid needs step_nm > 0 and stop_nm >= start_nm, got "
                         f"start={start_nm}, stop={stop_nm}, step={step_nm}")
    if not (200 <= start_nm and stop_nm <= 2500):
        raise InvalidValueError(f"wavelengths must lie in 200–2500 nm, got {start_nm}–{stop_nm}")
    n = int(round((stop_nm - start_nm) / step_nm)) + 1
    return start_nm + step_nm * np.arange(n, dtype=np.float64)


def _interp(table_wl: np.ndarray, table_values: np.ndarray, wavelengths_nm: np.ndarray) -> np.ndarray:
    """Linear interpolation along the first axis of `table_values`, constant outside."""
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    vals = np.asarray(table_values, dtype=np.float64)
    if vals.ndim == 1:
        return np.interp(wl, table_wl, vals)
    return np.stack([np.interp(wl, table_wl, vals[:, k]) for k in range(vals.shape[1])], axis=-1)


@lru_cache(maxsize=None)
def _cmfs_table() -> tuple[np.ndarray, np.ndarray]:
    import colour
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return cmfs.wavelengths.copy(), cmfs.values.copy()


def xyz_cmfs(wavelengths_nm: np.ndarray) -> np.ndarray:
    """CIE 1931 2° colour matching functions x̄ȳz̄, shape (Nλ, 3); zero outside 360–830 nm."""
    wl_t, vals = _cmfs_table()
    out = _interp(wl_t, vals, wavelengths_nm)
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    out[(wl < wl_t[0]) | (wl > wl_t[-1])] = 0.0
    return out


def luminous_efficiency(wavelengths_nm: np.ndarray) -> np.ndarray:
    """Photopic luminous efficiency V(λ) (= ȳ of CIE 1931)."""
    return xyz_cmfs(wavelengths_nm)[:, 1]


def blackbody_spd(temperature_K: float, wavelengths_nm: np.ndarray) -> np.ndarray:
    """Planck spectral radiance (W/sr/m²/nm) of a blackbody."""
    if temperature_K <= 0:
        raise InvalidValueError(f"blackbody temperature must be > 0 K, got {temperature_K}")
    import colour
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    values = colour.colorimetry.planck_law(np.atleast_1d(wl) * 1e-9, temperature_K) * 1e-9
    return np.asarray(values, dtype=np.float64).reshape(wl.shape)


def daylight_spd(cct_K: float, wavelengths_nm: np.ndarray) -> np.ndarray:
    """CIE daylight series SPD (relative, 100 at 560 nm) for a CCT in 4000–25000 K."""
    if not 4000 <= cct_K <= 25000:
        raise InvalidValueError(f"CIE daylight is defined for 4000–25000 K, got {cct_K} K")
    import colour
    xy = colour.temperature.CCT_to_xy_CIE_D(cct_K * 1.4388 / 1.4380)
    sd = colour.sd_CIE_illuminant_D_series(xy)
    return _interp(sd.wavelengths, sd.values, wavelengths_nm)


BLACKBODY_RANGE_K = (1000.0, 100000.0)
"""Blackbody temperatures an illuminant may have: below 1000 K the visible spectrum underflows to 0."""
ILLUMINANTS = ("D65", "D50", "D75", "A", "F2", "F11", "equal_energy")


def illuminant_spd(name: str, wavelengths_nm: np.ndarray) -> np.ndarray:
    """Relative spectral power (energy units) of a named illuminant.

    Names: D65, D50, D75, A, F2, F11, equal_energy, "daylight:<CCT K>", "blackbody:<T K>"."""
    import colour
    key = name.strip()
    if key.lower() == "equal_energy":
        return np.ones(np.asarray(wavelengths_nm).shape, dtype=np.float64)
    if ":" in key:
        kind, _, value = key.partition(":")
        try:
            temp = float(value)
        except ValueError as exc:
            raise InvalidValueError(f"illuminant '{name}': '{value}' is not a temperature in K") from exc
        if kind.lower() == "daylight":
            return daylight_spd(temp, wavelengths_nm)
        if kind.lower() == "blackbody":
            if not BLACKBODY_RANGE_K[0] <= temp <= BLACKBODY_RANGE_K[1]:
                raise InvalidValueError(f"illuminant '{name}': blackbody temperature must be a number in "
                                 f"{BLACKBODY_RANGE_K[0]:g}–{BLACKBODY_RANGE_K[1]:g} K")
            spd = blackbody_spd(temp, wavelengths_nm)
            return spd / spd.max()
    if key in colour.SDS_ILLUMINANTS and key in ILLUMINANTS:
        sd = colour.SDS_ILLUMINANTS[key]
        return _interp(sd.wavelengths, sd.values, wavelengths_nm)
    raise InvalidValueError(f"unknown illuminant '{name}'; allowed: {', '.join(ILLUMINANTS)}, "
                     "'daylight:<CCT K>' (4000–25000) or 'blackbody:<T K>' (1000–100000)")


@lru_cache(maxsize=256)
def checked_illuminant_name(name: str) -> str:
    """`name` when illuminant_spd knows it (raises with the allowed names otherwise); remembered,
    because every project validation asks and colour-science's lookup slugifies its whole table."""
    illuminant_spd(name, DEFAULT_WAVELENGTHS_NM)
    return name


@lru_cache(maxsize=None)
def _macbeth_table() -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    import colour
    sds = colour.SDS_COLOURCHECKERS["BabelColor Average"]
    names = tuple(sds.keys())
    wl = next(iter(sds.values())).wavelengths.copy()
    vals = np.stack([sds[n].values for n in names], axis=0)
    return wl, vals, names


def macbeth_reflectances(wavelengths_nm: np.ndarray) -> np.ndarray:
    """Spectral reflectances of the 24 ColorChecker patches (BabelColor average), shape (24, Nλ).

    Row order is the chart's reading order (dark skin … black). The table spans 380–730 nm;
    beyond it the end values are held."""
    wl_t, vals, _ = _macbeth_table()
    return _interp(wl_t, vals.T, wavelengths_nm).T.copy()


def macbeth_names() -> tuple[str, ...]:
    """Names of the 24 ColorChecker patches in row order."""
    return _macbeth_table()[2]


def luminance_from_photons(radiance_photons: np.ndarray, wavelengths_nm: np.ndarray) -> np.ndarray:
    """Luminance (cd/m²) of spectral radiance in photons/s/sr/m²/nm (wavelength on last axis).

    The same formula turns irradiance in photons/s/m²/nm into illuminance in lux."""
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    energy = photons_to_energy(radiance_photons, wl)
    weights = luminous_efficiency(wl) * band_widths_nm(wl) * MAX_LUMINOUS_EFFICACY_LM_W
    return energy @ weights


illuminance_from_photons = luminance_from_photons


def spd_photons_for_luminance(spd_energy: np.ndarray, wavelengths_nm: np.ndarray,
                              luminance_cd_m2: float) -> np.ndarray:
    """Scale a relative energy SPD so it has the given luminance; return it in photons/s/sr/m²/nm."""
    photons = energy_to_photons(spd_energy, wavelengths_nm)
    lum = float(luminance_from_photons(photons, wavelengths_nm))
    if lum <= 0:
        raise InvalidValueError("the spectrum has no power where the eye is sensitive (luminance 0); "
                         "cannot scale it to a luminance")
    return photons * (luminance_cd_m2 / lum)


def xyz_from_photons(photons: np.ndarray, wavelengths_nm: np.ndarray) -> np.ndarray:
    """CIE XYZ (Y in cd/m² for radiance, lux for irradiance) of photon spectra, last axis λ."""
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    energy = photons_to_energy(photons, wl)
    return energy @ (xyz_cmfs(wl) * band_widths_nm(wl)[:, None] * MAX_LUMINOUS_EFFICACY_LM_W)


def load_spectrum_csv(name: str, wavelengths_nm: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Read a spectrum CSV named relative to resources/ (validated: see spectrum_csv) and resample
    it. Outside the file's range the values are zero: a filter or QE curve that the file does not
    describe is taken to pass nothing. Returns (values (Nλ, K), names)."""
    from workbench.spectrum_csv import read_spectrum, resample
    table = read_spectrum(name)
    return resample(table, wavelengths_nm), list(table.names)

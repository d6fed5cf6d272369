"""Physical constants and photon/energy/photometric unit conversions.

Wavelengths are in nm; radiance in photons/s/sr/m²/nm (ISETCam's convention),
energy radiance in W/sr/m²/nm. Luminance in cd/m², illuminance in lux.
"""
from __future__ import annotations

import numpy as np

PLANCK_J_S = 6.62607015e-34
LIGHT_SPEED_M_S = 2.99792458e8
ELECTRON_CHARGE_C = 1.602176634e-19
MAX_LUMINOUS_EFFICACY_LM_W = 683.0


def photon_energy_J(wavelengths_nm: np.ndarray) -> np.ndarray:
    """Energy of one photon (J) at each wavelength (nm)."""
    return PLANCK_J_S * LIGHT_SPEED_M_S / (np.asarray(wavelengths_nm, dtype=np.float64) * 1e-9)


def energy_to_photons(energy: np.ndarray, wavelengths_nm: np.ndarray) -> np.ndarray:
    """Spectral energy (W/...) → photon rate (photons/s/...); wavelength on the last axis."""
    return np.asarray(energy, dtype=np.float64) / photon_energy_J(wavelengths_nm)


def photons_to_energy(photons: np.ndarray, wavelengths_nm: np.ndarray) -> np.ndarray:
    """Photon rate (photons/s/...) → spectral energy (W/...); wavelength on the last axis."""
    return np.asarray(photons, dtype=np.float64) * photon_energy_J(wavelengths_nm)


def band_widths_nm(wavelengths_nm: np.ndarray) -> np.ndarray:
    """Width (nm) of the band each sample represents (trapezoid-free midpoint rule).

    Uniform grids give the step; irregular grids give half the distance to each neighbour;
    a single wavelength gets a width of 1 nm (a delta line)."""
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    if wl.size == 1:
        return np.ones(1)
    edges = np.concatenate(([wl[0] - (wl[1] - wl[0]) / 2], (wl[1:] + wl[:-1]) / 2,
                            [wl[-1] + (wl[-1] - wl[-2]) / 2]))
    return np.diff(edges)

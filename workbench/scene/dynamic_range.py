"""A view's dynamic range: how far apart its bright and dark parts are.

Of the pixels with non-zero luminance (a render's unlit or unconverged pixels are 0 and have no
ratio), the ratio of a high to a low percentile (default 99.9 / 0.1: robust to a few extreme
pixels, e.g. Monte Carlo fireflies) and of the maximum to the minimum, each also in dB as
20·log10(ratio) (the image-sensor convention of EMVA 1288, so the two compare directly).
"""
from __future__ import annotations

import math

import numpy as np

from workbench.errors import InvalidValueError
from workbench.spectra import luminance_from_photons

DR_PERCENTILES = (0.1, 99.9)


def _dB(ratio: float) -> float | None:
    return 20.0 * math.log10(ratio) if math.isfinite(ratio) and ratio > 0 else None


def luminance_dynamic_range(luminance: np.ndarray, percentiles: tuple[float, float] = DR_PERCENTILES) -> dict:
    """Dynamic range of a luminance map (any unit): percentile and max/min ratios of its non-zero
    values, in ratio and dB; None entries when no pixel is lit."""
    lo_pct, hi_pct = percentiles
    if not 0.0 <= lo_pct < hi_pct <= 100.0:
        raise InvalidValueError(f"percentiles must satisfy 0 ≤ low < high ≤ 100, got {percentiles}")
    values = np.asarray(luminance, dtype=np.float64).ravel()
    if not np.all(np.isfinite(values)) or np.any(values < 0):
        raise InvalidValueError("luminance must be finite and ≥ 0")
    lit = values[values > 0]
    out = {"percentiles": [lo_pct, hi_pct], "fraction_zero": float(1.0 - lit.size / max(values.size, 1))}
    if lit.size == 0:
        return out | {"low": None, "high": None, "ratio": None, "dB": None, "min": None, "max": None,
                      "max_min_ratio": None, "max_min_dB": None}
    low, high = (float(v) for v in np.percentile(lit, [lo_pct, hi_pct]))
    vmin, vmax = float(lit.min()), float(lit.max())
    return out | {"low": low, "high": high, "ratio": high / low, "dB": _dB(high / low), "min": vmin, "max": vmax,
                  "max_min_ratio": vmax / vmin, "max_min_dB": _dB(vmax / vmin)}


def scene_dynamic_range(radiance_photons: np.ndarray, wavelengths_nm: np.ndarray,
                        percentiles: tuple[float, float] = DR_PERCENTILES) -> dict:
    """Dynamic range (luminance_dynamic_range) of a spectral radiance image in photons/s/sr/m²/nm
    (H×W×Nλ): its luminance in cd/m² (for an irradiance image, illuminance in lx)."""
    return luminance_dynamic_range(luminance_from_photons(radiance_photons, wavelengths_nm), percentiles)

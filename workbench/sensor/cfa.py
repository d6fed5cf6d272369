"""Colour-filter-array layouts and the effective spectral QE of each channel."""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from workbench.errors import InvalidValueError
from workbench.spectra import load_spectrum_csv

# Channel letters in their canonical order; a pattern's channel_names keep this order.
_CANONICAL = ("R", "G", "B", "C", "W", "M")

# The grid (nm) on which the sensor's spectral curves are sampled where no spectrum of the scene
# sets one: the film of a render in the sensor's own channels, and the ISP's colour fit for it.
SENSOR_SPECTRAL_GRID_NM = np.arange(350.0, 1000.1, 5.0)


def cfa_layout(pattern: str) -> tuple[np.ndarray, list[str]]:
    """(tile, channel_names) of a CFA pattern name.

    The name reads the 2×2 tile row by row ('GRBG' = G R / B G); pixel (r, c) has channel
    channel_names[tile[r % 2, c % 2]]. 'MONO' is a tile of one channel 'M' (no colour filter)."""
    key = pattern.upper()
    if key == "MONO":
        return np.zeros((2, 2), dtype=np.int64), ["M"]
    if len(key) != 4 or any(ch not in _CANONICAL[:-1] for ch in key):
        raise InvalidValueError(f"unknown CFA pattern '{pattern}'; allowed: RGGB, GRBG, GBRG, BGGR, RCCC, RCCB, "
                         "RGBW, MONO")
    names = [ch for ch in _CANONICAL if ch in key]
    tile = np.array([names.index(ch) for ch in key], dtype=np.int64).reshape(2, 2)
    return tile, names


@lru_cache(maxsize=32)
def _channel_qe_cached(pattern: str, filter_file: str | None, photodiode_qe_file: str | None,
                       ir_cut_file: str | None, wl_key: tuple[float, ...]) -> np.ndarray:
    wl = np.asarray(wl_key, dtype=np.float64)
    _, names = cfa_layout(pattern)
    common = np.ones(wl.size)
    if photodiode_qe_file is not None:
        common = common * load_spectrum_csv(photodiode_qe_file, wl)[0][:, 0]
    if ir_cut_file is not None:
        common = common * load_spectrum_csv(ir_cut_file, wl)[0][:, 0]
    qe = np.empty((wl.size, len(names)))
    if filter_file is not None:
        filters, filter_names = load_spectrum_csv(filter_file, wl)
    for k, ch in enumerate(names):
        qe[:, k] = common if ch == "M" else filters[:, filter_names.index(ch)] * common
    qe = np.clip(qe, 0.0, 1.0)
    qe.flags.writeable = False
    return qe


def channel_qe(params, wavelengths_nm: np.ndarray) -> np.ndarray:
    """Effective QE (Nλ, K) of each CFA channel: colour filter × IR-cut filter × photodiode QE.

    Curves are zero outside their files' wavelength ranges. The result is cached and read-only."""
    wl = np.asarray(wavelengths_nm, dtype=np.float64).ravel()
    return _channel_qe_cached(params.cfa_pattern, params.filter_file, params.photodiode_qe_file,
                              params.ir_cut_file, tuple(wl.tolist()))


def channel_index_map(tile: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """rows×cols array of each pixel's channel index."""
    th, tw = tile.shape
    return np.tile(tile, (rows // th + 1, cols // tw + 1))[:rows, :cols]

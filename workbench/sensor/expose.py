"""Electrons → volts → DN for one exposure (ISETCam's sensorAddNoise + analog2digital).

Order (noise_flag 2): dark current → photon shot noise (true Poisson on signal + dark electrons)
→ read noise → PRNU/DSNU → column FPN → analog gain/offset → clip to [0, swing] → quantise
DN = round(v / (swing / 2^bits)), limited to 2^bits − 1.
The fixed patterns (PRNU, DSNU, column FPN) come from params.seed and are the same every frame;
temporal noise comes from the `rng` passed in: it seeds a fixed number of row blocks, each read
out by one compiled pass (sensor.kernels) with its own SFC64 streams for shot and read noise, so a
given rng state gives the same image on any machine and with any number of threads; large frames
run their blocks in threads.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from workbench.compute.pixel_threads import BLOCKS, map_row_blocks
from workbench.errors import InvalidValueError
from workbench.sensor.cfa import cfa_layout, channel_qe
from workbench.sensor.image import SensorImage
from workbench.sensor.kernels import read_out_block, sfc64_state
from workbench.sensor.params import SensorParams

SATURATION_CAP = 1000.0
"""Mean electrons are capped at this many times the level that saturates the output (keeps the
Poisson draw finite for HDR input such as the sun; such pixels clip anyway)."""


@lru_cache(maxsize=8)
def _fixed_patterns(rows: int, cols: int, seed: int, prnu_sigma_pct: float, dsnu_sigma_V: float,
                    col_gain_sigma_pct: float, col_offset_sigma_V: float, analog_gain: float,
                    analog_offset_V: float) -> tuple[np.ndarray | float, np.ndarray | float]:
    """(A, B) with v_out = A·v + B: PRNU, DSNU, column FPN and analog gain/offset in one affine map.

    A and B are rows×cols float32 maps when any fixed pattern is on, else scalars. Gains are
    limited to ≥ 0 (a pixel cannot invert its signal)."""
    if not (prnu_sigma_pct or dsnu_sigma_V or col_gain_sigma_pct or col_offset_sigma_V):
        return float(analog_gain), float(analog_offset_V)
    rng = np.random.default_rng([seed, 0xF1CED])
    prnu = 1.0 + rng.standard_normal((rows, cols), dtype=np.float32) * np.float32(prnu_sigma_pct / 100)
    dsnu = rng.standard_normal((rows, cols), dtype=np.float32) * np.float32(dsnu_sigma_V)
    col_gain = 1.0 + rng.standard_normal(cols, dtype=np.float32) * np.float32(col_gain_sigma_pct / 100)
    col_offset = rng.standard_normal(cols, dtype=np.float32) * np.float32(col_offset_sigma_V)
    np.maximum(prnu, 0.0, out=prnu)
    np.maximum(col_gain, 0.0, out=col_gain)
    a = (analog_gain * prnu * col_gain[None, :]).astype(np.float32)
    b = (analog_gain * (dsnu * col_gain[None, :] + col_offset[None, :]) + analog_offset_V).astype(np.float32)
    a.flags.writeable = False
    b.flags.writeable = False
    return a, b


def fixed_patterns(params: SensorParams) -> tuple[np.ndarray | float, np.ndarray | float]:
    """The sensor's affine output map (A, B), v_out = A·v + B, cached per parameter set."""
    return _fixed_patterns(params.rows, params.cols, params.seed, params.prnu_sigma_pct,
                           params.dsnu_sigma_V, params.column_fpn_gain_sigma_pct,
                           params.column_fpn_offset_sigma_V, params.analog_gain, params.analog_offset_V)


def _exposure_map(exposure_s, tile_shape: tuple[int, int], rows: int, cols: int) -> np.ndarray | float:
    t = np.asarray(exposure_s, dtype=np.float64)
    if t.ndim == 0:
        t_val = float(t)
        if not (0.0 <= t_val <= 3600.0):
            raise InvalidValueError(f"sensor: exposure_s must lie in 0–3600 s, got {t_val}")
        return t_val
    if t.shape != tile_shape:
        raise InvalidValueError(f"sensor: per-CFA exposure must have the CFA tile shape {tile_shape}, got {t.shape}")
    if not (np.all(t >= 0) and np.all(t <= 3600.0)):
        raise InvalidValueError(f"sensor: per-CFA exposures must lie in 0–3600 s, got {t.tolist()}")
    return np.tile(t.astype(np.float32), (rows // t.shape[0] + 1, cols // t.shape[1] + 1))[:rows, :cols]


_NO_MAP = np.zeros((0, 0), dtype=np.float32)       # a kernel's per-pixel map argument when a scalar is used


def _block(sl: slice, rate: np.ndarray, t, params: SensorParams, seed: int, a, b,
           electrons: np.ndarray, volts: np.ndarray, dn: np.ndarray | None) -> int:
    """Simulate rows `sl` of the frame in place (runs in a worker thread; the kernel releases the
    GIL). Shot noise and read noise each draw from their own SFC64 stream of the block's seed.
    Returns how many rates of the block were NaN, infinite or negative."""
    flag = params.noise_flag
    cap = SATURATION_CAP * (params.voltage_swing_V + abs(params.analog_offset_V)) / (
        params.conversion_gain_V_per_e * params.analog_gain)
    t_map = t[sl] if isinstance(t, np.ndarray) else _NO_MAP
    a_map = a[sl] if isinstance(a, np.ndarray) else _NO_MAP
    b_map = b[sl] if isinstance(b, np.ndarray) else _NO_MAP
    return read_out_block(rate[sl], t_map, 0.0 if isinstance(t, np.ndarray) else float(t),
                   params.dark_current_e_per_s if flag == 2 else 0.0, min(cap, 1e15), flag >= 1,
                   params.conversion_gain_V_per_e, params.read_noise_V if flag == 2 else 0.0,
                   a_map, b_map, 0.0 if isinstance(a, np.ndarray) else float(a),
                   0.0 if isinstance(b, np.ndarray) else float(b), flag >= 0, params.voltage_swing_V,
                   1.0 / params.lsb_V, float(params.max_dn), dn is not None,
                   sfc64_state([seed, 0]), sfc64_state([seed, 1]),
                   electrons[sl], volts[sl], _NO_MAP if dn is None else dn[sl])


def _refuse_invalid_rates(rate: np.ndarray) -> None:
    """Raise InvalidValueError if any rate (e⁻/s) is NaN, infinite or negative."""
    if rate.size and not (rate.min() >= 0 and rate.max() < np.inf):
        raise InvalidValueError("sensor: signal rate (e⁻/s) must be finite and ≥ 0; it holds NaN, Inf or negatives")


def signal_rate_to_sensor_image(signal_rate_e_per_s: np.ndarray, params: SensorParams, exposure_s,
                                rng: np.random.Generator | None = None, *,
                                wavelengths_nm: np.ndarray | None = None) -> SensorImage:
    """One exposure of a rows×cols mean electron-rate image (e⁻/s) → SensorImage.

    exposure_s: seconds, or an array of the CFA tile's shape (per-CFA exposure).
    rng: temporal-noise generator (default: a new one from params.seed).
    wavelengths_nm: wavelengths of the optical image, to record the channels' QE in the result."""
    rate = np.asarray(signal_rate_e_per_s)
    if rate.shape != (params.rows, params.cols):
        raise InvalidValueError(f"sensor: signal rate has shape {rate.shape}, the sensor is "
                         f"{params.rows}×{params.cols} pixels")
    if rate.dtype != np.float32:
        rate = rate.astype(np.float32)
    tile, names = cfa_layout(params.cfa_pattern)
    try:
        t = _exposure_map(exposure_s, tile.shape, params.rows, params.cols)
    except InvalidValueError:
        _refuse_invalid_rates(rate)           # a NaN exposure from auto-exposure comes from the rates
        raise
    if rng is None:
        rng = np.random.default_rng([params.seed, 2])
    a, b = fixed_patterns(params) if params.noise_flag == 2 else (params.analog_gain, params.analog_offset_V)
    electrons = np.empty(rate.shape, dtype=np.float32)
    volts = np.empty(rate.shape, dtype=np.float32)
    dn = np.empty(rate.shape, dtype=np.float32) if params.bit_depth else None
    seeds = [int(s) for s in rng.integers(0, 2 ** 63, size=BLOCKS)]
    invalid = map_row_blocks(lambda i, rows: _block(rows, rate, t, params, seeds[i], a, b, electrons, volts, dn),
                             params.rows, rate.size)
    if sum(invalid):                    # counted by the read-out, which read them as 0
        _refuse_invalid_rates(rate)
    qe = (channel_qe(params, wavelengths_nm) if wavelengths_nm is not None
          else np.zeros((0, len(names))))
    exposure = float(t) if not isinstance(t, np.ndarray) else np.asarray(exposure_s, dtype=np.float64)
    return SensorImage(electrons=electrons, volts=volts, dn=volts if dn is None else dn, cfa_tile=tile.copy(),
                       channel_names=list(names), pattern=params.cfa_pattern, qe=qe,
                       wavelengths_nm=(np.asarray(wavelengths_nm, dtype=np.float64) if wavelengths_nm is not None
                                       else np.zeros(0)),
                       exposure_s=exposure, max_dn=params.max_dn,
                       meta={"noise_flag": params.noise_flag, "lsb_V": params.lsb_V,
                             # the ISP subtracts this black level (code of the analog offset)
                             "black_level_dn": max(0.0, params.analog_offset_V) / params.lsb_V,
                             "bit_depth": params.bit_depth,
                             "conversion_gain_V_per_e": params.conversion_gain_V_per_e,
                             "voltage_swing_V": params.voltage_swing_V,
                             "analog_gain": params.analog_gain, "analog_offset_V": params.analog_offset_V})

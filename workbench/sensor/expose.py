"""Electrons → volts → DN for one exposure (ISETCam's sensorAddNoise + analog2digital).

Order (noise_flag 2): dark current → photon shot noise (true Poisson on signal + dark electrons)
→ read noise → PRNU/DSNU → column FPN → analog gain/offset → clip to [0, swing] → quantise
DN = round(v / (swing / 2^bits)), limited to 2^bits − 1.
The fixed patterns (PRNU, DSNU, column FPN) come from params.seed and are the same every frame;
temporal noise comes from the `rng` passed in. The frame is split into a fixed number of row
blocks, each with its own child generator, and the blocks run in threads (numpy releases the
GIL), so a given rng state gives the same image on any machine.
"""
from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from functools import lru_cache

import numpy as np

from workbench.errors import InvalidValueError
from workbench.sensor.cfa import cfa_layout, channel_qe
from workbench.sensor.image import SensorImage
from workbench.sensor.params import SensorParams

N_BLOCKS = 2
"""Row blocks per frame: fixed, so results do not depend on the number of threads."""
_PARALLEL_MIN_PIXELS = 1 << 16
SATURATION_CAP = 1000.0
"""Mean electrons are capped at this many times the level that saturates the output (keeps the
Poisson draw finite for HDR input such as the sun; such pixels clip anyway)."""

_pool: ThreadPoolExecutor | None = None
_pool_pid = -1
_pool_lock = threading.Lock()


def _executor() -> ThreadPoolExecutor:
    """The worker threads, created on first use and again in a forked child (whose copy of the
    pool has no threads)."""
    global _pool, _pool_pid
    with _pool_lock:
        if _pool is None or _pool_pid != os.getpid():
            _pool = ThreadPoolExecutor(max_workers=min(N_BLOCKS, os.cpu_count() or 1),
                                       thread_name_prefix="sensor")
            _pool_pid = os.getpid()
        return _pool


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


def _block(sl: slice, rate: np.ndarray, t, params: SensorParams, gen: np.random.Generator,
           a, b, electrons: np.ndarray, volts: np.ndarray, dn: np.ndarray | None) -> None:
    """Simulate rows `sl` of the frame in place (runs in a worker thread)."""
    flag = params.noise_flag
    g = np.float32(params.conversion_gain_V_per_e)
    t_blk = t[sl] if isinstance(t, np.ndarray) else np.float32(t)
    e = electrons[sl]
    np.multiply(rate[sl], t_blk, out=e)
    if flag == 2 and params.dark_current_e_per_s > 0:
        e += np.float32(params.dark_current_e_per_s) * t_blk
    a_blk = a[sl] if isinstance(a, np.ndarray) else np.float32(a)
    b_blk = b[sl] if isinstance(b, np.ndarray) else np.float32(b)
    cap = SATURATION_CAP * (params.voltage_swing_V + abs(params.analog_offset_V)) / (
        params.conversion_gain_V_per_e * params.analog_gain)
    np.minimum(e, np.float32(min(cap, 1e15)), out=e)
    if flag >= 1:
        e[...] = gen.poisson(e)
    v = volts[sl]
    np.multiply(e, g, out=v)
    if flag == 2 and params.read_noise_V > 0:
        z = gen.standard_normal(v.shape, dtype=np.float32)
        z *= np.float32(params.read_noise_V)
        v += z
    if flag >= 0:
        v *= a_blk
        v += b_blk
        np.clip(v, 0.0, np.float32(params.voltage_swing_V), out=v)
    if dn is not None:
        d = dn[sl]
        np.multiply(v, np.float32(1.0 / params.lsb_V), out=d)
        np.rint(d, out=d)
        np.clip(d, 0.0, np.float32(params.max_dn), out=d)


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
    if rate.size and not (rate.min() >= 0 and rate.max() < np.inf):
        raise InvalidValueError("sensor: signal rate (e⁻/s) must be finite and ≥ 0; it holds NaN, Inf or negatives")
    tile, names = cfa_layout(params.cfa_pattern)
    t = _exposure_map(exposure_s, tile.shape, params.rows, params.cols)
    if rng is None:
        rng = np.random.default_rng([params.seed, 2])
    a, b = fixed_patterns(params) if params.noise_flag == 2 else (params.analog_gain, params.analog_offset_V)
    electrons = np.empty(rate.shape, dtype=np.float32)
    volts = np.empty(rate.shape, dtype=np.float32)
    dn = np.empty(rate.shape, dtype=np.float32) if params.bit_depth else None
    rows = params.rows
    if rate.size >= _PARALLEL_MIN_PIXELS and params.noise_flag >= 1:
        edges = np.linspace(0, rows, N_BLOCKS + 1).astype(int)
        seeds = rng.integers(0, 2 ** 63, size=N_BLOCKS)
        jobs = [_executor().submit(_block, slice(edges[i], edges[i + 1]), rate, t, params,
                                   np.random.default_rng(seeds[i]), a, b, electrons, volts, dn)
                for i in range(N_BLOCKS)]
        for job in jobs:
            job.result()
    else:
        _block(slice(0, rows), rate, t, params, rng, a, b, electrons, volts, dn)
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

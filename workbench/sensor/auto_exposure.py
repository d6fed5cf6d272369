"""Auto-exposure (ISETCam autoExposure.m) on the noise-free mean signal, plus the EV bias.

Each method looks at the mean pixel voltage accumulated per second before the analog offset,
V₁ = analog_gain · conversion_gain · (signal + dark) e⁻/s (dark only with noise_flag 2), and
picks t so that the chosen statistic of the mean output A·V₁·t + offset reaches its target.
The result is t · 2^ev_bias, limited to [0, max_exposure_s]. Unlike ISETCam, V₁ is always
noise-free, so the exposure does not change from frame to frame.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from workbench.errors import InvalidValueError
from workbench.registry import Registry
from workbench.sensor.cfa import cfa_layout
from workbench.sensor.kernels import mean_f64, scale_rates
from workbench.sensor.params import SensorParams

AUTO_EXPOSURE_METHODS: Registry[Callable] = Registry("sensor.auto_exposure_method", "auto-exposure method")
"""name → fn(volts_per_s, params) -> exposure_s (a float, or an array of the CFA tile's shape)."""
register_auto_exposure = AUTO_EXPOSURE_METHODS.register


def _headroom_V(params: SensorParams, fraction: float) -> float:
    offset_V = params.analog_offset_V if params.noise_flag >= 0 else 0.0
    target = fraction * params.voltage_swing_V - offset_V
    if target <= 0:
        raise InvalidValueError(f"auto-exposure target {fraction} × {params.voltage_swing_V} V is at or below the "
                         f"analog offset {offset_V} V; raise auto_exposure_level or lower "
                         "analog_offset_V")
    return target


def _time_for(target_V: float, volts_per_s: float, params: SensorParams) -> float:
    return params.max_exposure_s if volts_per_s <= 0 else target_V / volts_per_s


@register_auto_exposure("mean")
def _mean(vps: np.ndarray, params: SensorParams) -> float:
    """Mean voltage = level · swing (ISETCam 'mean'; the paper's experiment uses level 0.4)."""
    return _time_for(_headroom_V(params, params.auto_exposure_level),
                     mean_f64(np.ascontiguousarray(vps, dtype=np.float32).reshape(-1)), params)


@register_auto_exposure("brightest")
def _brightest(vps: np.ndarray, params: SensorParams) -> float:
    """Brightest pixel reaches level · swing (ISETCam 'default'/'luminance'/'full')."""
    return _time_for(_headroom_V(params, params.auto_exposure_level), float(vps.max()), params)


@register_auto_exposure("percentile")
def _percentile(vps: np.ndarray, params: SensorParams) -> float:
    """The level-th percentile reaches the full swing (ISETCam 'specular')."""
    value = float(np.percentile(vps, 100.0 * params.auto_exposure_level))
    return _time_for(_headroom_V(params, 1.0), value, params)


@register_auto_exposure("cfa")
def _cfa(vps: np.ndarray, params: SensorParams) -> np.ndarray:
    """One exposure per CFA tile position: the brightest pixel of each reaches level · swing."""
    tile, _ = cfa_layout(params.cfa_pattern)
    th, tw = tile.shape
    target = _headroom_V(params, params.auto_exposure_level)
    out = np.empty(tile.shape)
    for i in range(th):
        for j in range(tw):
            sub = vps[i::th, j::tw]
            out[i, j] = _time_for(target, float(sub.max()) if sub.size else 0.0, params)
    return out


def auto_exposure(signal_rate_e_per_s: np.ndarray, params: SensorParams, method: str | None = None):
    """Exposure (s) picked by `method` (default params.auto_exposure_method), times 2^ev_bias.

    Returns a float, or an array of the CFA tile's shape for the 'cfa' method."""
    pick = AUTO_EXPOSURE_METHODS[method or params.auto_exposure_method]
    electrons_per_s = np.asarray(signal_rate_e_per_s, dtype=np.float32)
    gain = params.analog_gain if params.noise_flag >= 0 else 1.0
    dark_e_per_s = params.dark_current_e_per_s if params.noise_flag == 2 and params.dark_current_e_per_s > 0 else 0.0
    vps = np.empty(electrons_per_s.shape, dtype=np.float32)
    scale_rates(np.ascontiguousarray(electrons_per_s).reshape(-1), np.float32(dark_e_per_s),
                np.float32(gain * params.conversion_gain_V_per_e), vps.reshape(-1))
    t = np.clip(np.asarray(pick(vps, params), dtype=np.float64) * 2.0 ** params.ev_bias, 0.0, params.max_exposure_s)
    return float(t) if t.ndim == 0 else t


def resolve_exposure(signal_rate_e_per_s: np.ndarray, params: SensorParams):
    """The exposure a capture uses: params.exposure_s (× 2^ev_bias) if set, else auto-exposure."""
    if params.exposure_s is None:
        return auto_exposure(signal_rate_e_per_s, params)
    t0 = np.asarray(params.exposure_s, dtype=np.float64)
    t = np.clip(t0 * 2.0 ** params.ev_bias, 0.0, 3600.0)
    return float(t) if t.ndim == 0 else t


# how each method's rule reads, {level} as a percentage (the window says which rule a project uses)
AUTO_EXPOSURE_RULES = {"mean": "mean signal at {level} of the swing",
                       "brightest": "brightest pixel at {level} of the swing",
                       "percentile": "{level} percentile pixel at the full swing",
                       "cfa": "brightest pixel of each CFA position at {level} of the swing"}


def exposure_rule(method: str, level: float) -> str:
    """An auto-exposure rule in words: 'brightest pixel at 90 % of the swing'."""
    return AUTO_EXPOSURE_RULES.get(method, method + " at {level}").format(level=f"{100 * level:g} %")


def describe_exposure(params: SensorParams) -> str:
    """How a capture's exposure is chosen: the fixed exposure or the auto-exposure rule, with the
    EV bias and the auto-exposure's longest exposure."""
    bias = f", {params.ev_bias:+g} EV" if params.ev_bias else ""
    if params.exposure_s is not None:
        t = np.asarray(params.exposure_s, np.float64)
        return f"fixed {1e3 * float(t.mean()):.3g} ms{' (mean of the CFA tile)' if t.ndim else ''}{bias}"
    return (f"auto, {exposure_rule(params.auto_exposure_method, params.auto_exposure_level)}{bias} "
            f"(at most {params.max_exposure_s:g} s)")

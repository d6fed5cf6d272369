"""Measurements with no finite value (an SNR without noise, a ratio of nothing): written as null,
with the reason beside them, and shown as the reason in words, never as inf or a huge number.

    snr = finite_or_none(mean / sd)                       # None where sd is 0
    why = snr_unbounded_reason(sensor)                    # 'unbounded (noise off)'
    shown(value, why, "{:.4g}")                           # '12.3' or 'unbounded (noise off)'
"""
from __future__ import annotations

import math

NO_VALUE = "—"
RELATIVE_ZERO = 1e-9      # a measured σ below this share of the mean is floating-point rounding, not noise


def finite_or_none(value) -> float | None:
    """value as a float, or None where it is NaN, ±inf or missing."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def snr_unbounded_reason(sensor) -> str:
    """Why an SNR of this sensor has no finite value: its noise is off, or its read-out does not vary."""
    if sensor.noise_flag < 1:
        return "unbounded (noise off)"
    return "unbounded (the read-out does not vary)"


def measured_snr(mean: float, sd: float) -> float | None:
    """mean/sd of a measurement, None where sd is zero or only floating-point rounding of the mean."""
    if not sd > RELATIVE_ZERO * abs(mean) or sd <= 0:
        return None
    return mean / sd


def shown(value, reason: str | None = None, fmt: str = "{:.4g}") -> str:
    """A value for a table or terminal: formatted, or the reason it has none (else a dash)."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return reason or NO_VALUE
    return fmt.format(value) if isinstance(value, float) else str(value)

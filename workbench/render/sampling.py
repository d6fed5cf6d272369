"""Samples per pixel from an error target: Monte Carlo error falls as c/√spp.

c is measured per scene from two independent renders a, b at the same spp:
σ = rms(a − b)/√2 (the per-pixel noise of one render), relative to the mean signal, times √spp.
Facts (research/mitsuba.md §4): c ≈ 0.76 broadband and ≈ 4.55 per 10-nm band in the city."""
from __future__ import annotations

import math

import numpy as np

from workbench.errors import InvalidValueError


def noise_constant(a: np.ndarray, b: np.ndarray, spp: int, metric: str = "broadband") -> float:
    """c in rel_error = c/√spp from two independent H×W×K renders at `spp` each.

    metric 'broadband': error of the channel sum relative to its mean; 'per_channel': the mean
    over channels of each channel's relative RMS error (channels with zero mean are skipped)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 3:
        raise InvalidValueError(f"noise_constant needs two H×W×K images of one shape, got {a.shape}, {b.shape}")
    if metric == "broadband":
        sa, sb = a.sum(axis=2), b.sum(axis=2)
        mean = 0.5 * (sa.mean() + sb.mean())
        rel = np.sqrt(np.mean((sa - sb) ** 2) / 2) / mean if mean > 0 else 0.0
    elif metric == "per_channel":
        mean = 0.5 * (a.mean(axis=(0, 1)) + b.mean(axis=(0, 1)))
        rms = np.sqrt(np.mean((a - b) ** 2, axis=(0, 1)) / 2)
        live = mean > 0
        rel = float(np.mean(rms[live] / mean[live])) if live.any() else 0.0
    else:
        raise InvalidValueError(f"error metric '{metric}' is not allowed; allowed: broadband, per_channel")
    return float(rel * math.sqrt(spp))


def spp_for_error(c: float, rel_error: float, max_spp: int = 1 << 20) -> int:
    """Samples per pixel that bring the relative error c/√spp down to rel_error (≥ 1, ≤ max_spp)."""
    if not rel_error > 0:
        raise InvalidValueError(f"rel_error must be > 0, got {rel_error}")
    if not c >= 0 or not math.isfinite(c):
        raise InvalidValueError(f"noise constant c must be finite and ≥ 0, got {c}")
    return int(min(max(math.ceil((c / rel_error) ** 2), 1), max_spp))


def spp_for_shot_noise(c: float, mean_electrons: float, noise_ratio: float = 0.3,
                       max_spp: int = 1 << 20) -> int:
    """spp whose render noise is `noise_ratio` × the photon shot noise 1/√N_e of the exposure.

    With ratio 0.3 the render adds √(1 + 0.09) − 1 ≈ 4.4 % to the total noise."""
    if not mean_electrons > 0:
        raise InvalidValueError(f"mean_electrons must be > 0, got {mean_electrons}")
    if not 0 < noise_ratio <= 10:
        raise InvalidValueError(f"noise_ratio must be in (0, 10], got {noise_ratio}")
    return spp_for_error(c, noise_ratio / math.sqrt(mean_electrons), max_spp)

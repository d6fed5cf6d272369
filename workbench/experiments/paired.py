"""Paired statistics of detection runs: how two conditions differ, with two 95 % intervals.

Two conditions A and B are *paired* when they share a seed (the same initial weights, batch order
and training noise where the conditions allow it) and are tested on the same captures of the
same test frames. Their difference is read on the pairs, never by comparing two separate bands:

    seed interval       d_s = A_s − B_s for each seed s; mean ± t(0.975, n−1)·sd/√n
                        (Student t; what another set of seeds would give)
    test-set interval   the same mean difference on each of the runs' shared bootstrap resamples
                        of the test frames (evaluate.bootstrap_weights): the 2.5 and 97.5
                        percentiles (what another test set of this size would give)

A contrast is a function of a run's mAPs (e.g. mAP at EV −2 divided by mAP at EV 0), evaluated
on the point estimates for the seed interval and on every resample for the test-set interval.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from workbench.errors import InvalidValueError


@dataclass(frozen=True)
class Interval:
    """A mean paired difference with its seed (Student t) and test-set (bootstrap) 95 % intervals."""

    mean: float
    n: int
    sd: float | None
    t_low: float | None
    t_high: float | None
    boot_low: float | None
    boot_high: float | None

    def to_dict(self) -> dict:
        return asdict(self)

    def side(self) -> int:
        """+1 when both intervals lie above 0, −1 when both lie below, 0 otherwise (or unknown)."""
        return self.side_of(0.0)

    def side_of(self, margin: float) -> int:
        """+1 when both intervals lie above `margin`, −1 when both lie below it, else 0."""
        bounds = (self.t_low, self.t_high, self.boot_low, self.boot_high)
        if any(b is None for b in bounds):
            return 0
        if min(self.t_low, self.boot_low) > margin:
            return 1
        if max(self.t_high, self.boot_high) < margin:
            return -1
        return 0


def t_interval(values) -> tuple[float, float | None, float | None, float | None]:
    """(mean, sd, low, high) of a 95 % Student-t interval for the mean; None where n < 2."""
    from scipy import stats
    v = np.asarray(values, dtype=np.float64)
    mean = float(v.mean())
    if v.size < 2:
        return mean, None, None, None
    sd = float(v.std(ddof=1))
    half = float(stats.t.ppf(0.975, v.size - 1) * sd / np.sqrt(v.size))
    return mean, sd, mean - half, mean + half


def percentile_interval(samples) -> tuple[float | None, float | None]:
    """The 2.5 and 97.5 percentiles of the finite samples (None when there are fewer than 20)."""
    s = np.asarray(samples, dtype=np.float64)
    s = s[np.isfinite(s)]
    if s.size < 20:
        return None, None
    lo, hi = np.percentile(s, [2.5, 97.5])
    return float(lo), float(hi)


def paired_difference(a, b, a_boot=None, b_boot=None) -> Interval:
    """A − B on paired seeds: a, b are the per-seed values (same order); a_boot, b_boot the
    per-seed bootstrap values (seeds × resamples, the same resamples in both), or None."""
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    if d.ndim != 1 or d.size == 0:
        raise InvalidValueError(f"paired_difference needs one value per seed, got shape {d.shape}")
    mean, sd, lo, hi = t_interval(d)
    boot_lo = boot_hi = None
    if a_boot is not None and b_boot is not None:
        diff = np.asarray(a_boot, dtype=np.float64) - np.asarray(b_boot, dtype=np.float64)
        if diff.shape[0] != d.size:
            raise InvalidValueError(f"bootstrap values for {diff.shape[0]} seeds, point values for {d.size}")
        boot_lo, boot_hi = percentile_interval(diff.mean(axis=0))
    return Interval(mean, int(d.size), sd, lo, hi, boot_lo, boot_hi)


def mean_interval(values, boot=None) -> Interval:
    """The mean of per-seed values itself (a paired difference against 0), with both intervals."""
    values = np.asarray(values, dtype=np.float64)
    zeros = None if boot is None else np.zeros_like(np.asarray(boot, dtype=np.float64))
    return paired_difference(values, np.zeros_like(values), boot, zeros)

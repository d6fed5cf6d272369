"""Paired statistics of detection runs: how two conditions differ, with 95 % intervals.

Two conditions A and B are *paired* when they share a seed (the same initial weights, batch order
and training noise where the conditions allow it) and are tested on the same captures of the
same test frames. Their difference is read on the pairs, never by comparing two separate bands.
With V[s, b] the per-seed difference on the runs' shared test-set resample b
(evaluate.bootstrap_weights: index b is the same resample in every run):

    two-level interval  (the one verdicts read) each draw resamples the n seeds with replacement
                        (the same seeds for A and B) and, independently, one resample b; its
                        value is mean_b + c·(mean of the drawn seeds' V[s, b] − mean_b), mean_b
                        the mean of V[:, b] over all seeds; the 2.5 and 97.5 percentiles of
                        TWO_LEVEL_DRAWS draws. c = t(0.975, n−1)/z(0.975)·√(n/(n−1)) widens the
                        seed resampling, which alone has (n−1)/n of the seed variance and normal
                        tails, to the seed t-interval's width: unwidened, in the simulation of
                        tests/experiments/test_two_level.py (5 seeds, seed and test-set variation
                        comparable) it covered 90.5 % and gave 4.3 % false "supported".
                        It carries both sources of variation: other seeds and another test set.
    one-sided p         against a bound, from the same draws: (1 + #draws on the bound's other
                        side, bound included) / (1 + #draws).
    seed interval       d_s = A_s − B_s for each seed s; mean ± t(0.975, n−1)·sd/√n (descriptive:
                        another set of seeds on this test set)
    test-set interval   the mean difference over seeds on each resample b: its 2.5 and 97.5
                        percentiles (descriptive: another test set for these seeds)

A contrast is a function of a run's mAPs (e.g. mAP at EV −2 divided by mAP at EV 0), evaluated
on the point estimates for the seed interval and on every resample for the others.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from workbench.errors import InvalidValueError

TWO_LEVEL_DRAWS = 4000
DRAW_SEED = 0x706169                  # 'pai': every contrast draws the same seeds and resamples


@dataclass(frozen=True)
class Interval:
    """A mean paired difference with its seed (Student t), test-set (bootstrap) and two-level 95 %
    intervals, and the two-level one-sided p-values at some bounds (p_key → p)."""

    mean: float
    n: int
    sd: float | None
    t_low: float | None
    t_high: float | None
    boot_low: float | None
    boot_high: float | None
    h_low: float | None = None
    h_high: float | None = None
    p_values: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """A flat row: the fields, with each p-value under its own p_key."""
        row = asdict(self)
        p_values = row.pop("p_values")
        return {**row, **p_values}


def p_key(direction: int, bound: float) -> str:
    """The row key of the p-value for 'the difference lies above (+1) / below (−1) bound'."""
    return f"p_{'above' if direction > 0 else 'below'}_{bound:+g}"


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


def two_level_draws(values, draws: int = TWO_LEVEL_DRAWS, seed: int = DRAW_SEED) -> np.ndarray:
    """The finite two-level draws (module docstring) of the mean over seeds of values (seeds ×
    resamples); none with fewer than 2 seeds."""
    from scipy import stats
    v = np.asarray(values, dtype=np.float64)
    n, resamples = v.shape
    if n < 2 or resamples == 0:
        return np.empty(0)
    rng = np.random.default_rng([seed, n, resamples])
    seeds = rng.integers(0, n, size=(draws, n))
    b = rng.integers(0, resamples, size=draws)
    centre = v.mean(axis=0)[b]
    widen = stats.t.ppf(0.975, n - 1) / stats.norm.ppf(0.975) * np.sqrt(n / (n - 1))
    out = centre + widen * (v[seeds, b[:, None]].mean(axis=1) - centre)
    return out[np.isfinite(out)]


def one_sided_p(draws: np.ndarray, bound: float, direction: int) -> float | None:
    """p-value of 'the difference lies above (+1) / below (−1) bound' from two-level draws:
    (1 + #draws not beyond it) / (1 + #draws); None with fewer than 20 draws."""
    if draws.size < 20:
        return None
    against = np.count_nonzero(draws <= bound if direction > 0 else draws >= bound)
    return float((1 + against) / (1 + draws.size))


def paired_difference(a, b, a_boot=None, b_boot=None, bounds=()) -> Interval:
    """A − B on paired seeds: a, b are the per-seed values (same order); a_boot, b_boot the
    per-seed bootstrap values (seeds × resamples, the same resamples in both), or None; the
    two-level p-values above and below each of `bounds` (None without resamples)."""
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    if d.ndim != 1 or d.size == 0:
        raise InvalidValueError(f"paired_difference needs one value per seed, got shape {d.shape}")
    mean, sd, lo, hi = t_interval(d)
    draws = np.empty(0)
    boot_lo = boot_hi = None
    if a_boot is not None and b_boot is not None:
        diff = np.asarray(a_boot, dtype=np.float64) - np.asarray(b_boot, dtype=np.float64)
        if diff.shape[0] != d.size:
            raise InvalidValueError(f"bootstrap values for {diff.shape[0]} seeds, point values for {d.size}")
        boot_lo, boot_hi = percentile_interval(diff.mean(axis=0))
        draws = two_level_draws(diff)
    h_lo, h_hi = percentile_interval(draws)
    p_values = {p_key(direction, bound): one_sided_p(draws, bound, direction)
                for bound in bounds for direction in (1, -1)}
    return Interval(mean, int(d.size), sd, lo, hi, boot_lo, boot_hi, h_lo, h_hi, p_values)

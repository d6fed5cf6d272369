"""The two-level interval and a claim's verdict against simulated runs with a known difference.

Each replication draws a fresh test set and fresh seeds. A run's score on frame j is
    condition mean + frame difficulty (both conditions) + condition × frame + seed (both
    conditions: paired) + condition × seed + noise,
and its mAP on test-set resample b is the frame scores averaged with resample b's multiplicities
(the same resamples for every run, as evaluate.bootstrap_weights gives). The paired difference
A − B then varies by seed (sd SIGMA_SEED per seed) and by test set (sd SIGMA_TEST of the
test-set mean) with equal shares of the variance of the mean over N_SEEDS seeds:
SIGMA_SEED / √N_SEEDS = SIGMA_TEST. The truth, TRUE_DIFFERENCE, is the expectation over both.
"""
from __future__ import annotations

import numpy as np

from workbench.experiments.analysis import claims
from workbench.experiments.paired import paired_difference

N_SEEDS, FRAMES, RESAMPLES, REPLICATIONS = 5, 120, 200, 2000
SIGMA_TEST = 0.02
SIGMA_SEED = SIGMA_TEST * np.sqrt(N_SEEDS)
TRUE_DIFFERENCE = 0.0                       # exactly at claim 1's bound (resnet18 − mobile drop < 0)
MC_SE = np.sqrt(0.025 * 0.975 / REPLICATIONS)   # 0.0035: Monte Carlo standard error of a 2.5 % rate


def _replications(rng):
    """REPLICATIONS × 2 conditions × N_SEEDS: full-test-set values and values on each resample."""
    r, n, m = REPLICATIONS, N_SEEDS, FRAMES
    shape = (r, 1, 1, m)
    frames = rng.normal(0.5, 0.1, shape) + SIGMA_TEST * np.sqrt(m / 2) * rng.standard_normal((r, 2, 1, m))
    seeds = 0.05 * rng.standard_normal((r, 1, n, 1)) + SIGMA_SEED / np.sqrt(2) * rng.standard_normal((r, 2, n, 1))
    scores = frames + seeds + 0.02 * rng.standard_normal((r, 2, n, m))
    scores[:, 0] += TRUE_DIFFERENCE
    weights = rng.multinomial(m, np.full(m, 1.0 / m), size=RESAMPLES) / m        # RESAMPLES × frames
    return scores.mean(axis=-1), scores @ weights.T


def test_two_level_interval_covers_and_holds_false_support_at_the_bound():
    points, resampled = _replications(np.random.default_rng(20240611))
    covered = supported = 0
    for k in range(REPLICATIONS):
        iv = paired_difference(points[k, 0], points[k, 1], resampled[k, 0], resampled[k, 1], bounds=(0.0,))
        covered += iv.h_low <= TRUE_DIFFERENCE <= iv.h_high
        row = {"contrast": "relative drop resnet18 − mobile", "net": "both", "test_ev": "all", **iv.to_dict()}
        supported += claims([], [row])[0]["verdict"] == "supported"
    coverage, false_supported = covered / REPLICATIONS, supported / REPLICATIONS
    print(f"two-level coverage {coverage:.4f}, false 'supported' at the bound {false_supported:.4f} "
          f"({REPLICATIONS} replications, tolerance 2 × {MC_SE:.4f})")
    assert 0.93 <= coverage <= 0.97
    assert false_supported <= 0.025 + 2 * MC_SE

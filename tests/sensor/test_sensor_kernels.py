"""The compiled sensor noise against its oracles: below λ = 10 the same SFC64 stream gives
numpy's own Poisson draws (bit for bit), from 10 up the draws follow the Poisson probabilities,
the normal draws are numpy's, and a block read-out equals a numpy implementation of the
documented order of operations."""
import math

import mpmath
import numpy as np
import pytest
from scipy import stats

from workbench.compute import pixel_threads
from workbench.compute.local import THREAD_BUDGET_ENV
from workbench.sensor import kernels
from workbench.sensor import expose
from workbench.sensor.expose import signal_rate_to_sensor_image
from workbench.sensor.params import SensorParams


def _numpy_generator(seed) -> np.random.Generator:
    return np.random.Generator(np.random.SFC64(seed))


def _state(gen: np.random.Generator) -> np.ndarray:
    return np.asarray(gen.bit_generator.state["state"]["state"], dtype=np.uint64)


def test_poisson_draws_below_ten_equal_numpys_on_the_same_stream():
    """Below λ = 10 the kernel multiplies uniforms as numpy does: the same draws, bit for bit."""
    rng = np.random.default_rng(0)
    means = np.concatenate([[0.0, 1e-300, 1e-6, 9.999999], rng.uniform(0, 10, 300_000)])
    for dtype in (np.float64, np.float32):
        lam = means.astype(dtype)
        state = kernels.sfc64_state([7, 1])
        out = np.empty(lam.size)
        kernels.poisson_fill(lam, out, state)
        gen = _numpy_generator([7, 1])
        np.testing.assert_array_equal(out, gen.poisson(lam))
        np.testing.assert_array_equal(state, _state(gen))      # the stream continues where numpy's does


def _poisson_fit_p_value(draws: np.ndarray, lam: float) -> float:
    """Chi-square p-value of whole-number draws against Poisson(lam); bins with fewer than 5
    expected are pooled into the two tails."""
    lo, hi = int(stats.poisson.ppf(1e-7, lam)), int(stats.poisson.isf(1e-7, lam))
    k = np.arange(lo, hi + 1)
    observed = np.bincount(np.clip(draws.astype(np.int64), lo, hi) - lo, minlength=k.size).astype(float)
    expected = stats.poisson.pmf(k, lam)
    expected[0], expected[-1] = stats.poisson.cdf(lo, lam), stats.poisson.sf(hi - 1, lam)
    expected *= draws.size
    keep = expected >= 5
    observed = np.concatenate([observed[keep], [observed[~keep].sum()]])
    expected = np.concatenate([expected[keep], [expected[~keep].sum()]])
    if expected[-1] == 0:
        observed, expected = observed[:-1], expected[:-1]
    return stats.chisquare(observed, expected * observed.sum() / expected.sum()).pvalue


PD_MEANS = [10.0, 10.5, 13.7, 24.9, 55.5, 300.2, 4321.0, 2.5e5, 1e7]


@pytest.mark.parametrize("lam", PD_MEANS)
def test_poisson_draws_from_ten_up_follow_the_poisson_distribution(lam):
    """Method PD (λ ≥ 10) against the Poisson probabilities: chi-square on a million draws,
    mean and variance within 5 standard errors (SE(var) = √((λ + 2λ²)/N))."""
    n = 1_000_000
    draws = np.empty(n)
    kernels.poisson_fill(np.full(n, lam), draws, kernels.sfc64_state([11, PD_MEANS.index(lam)]))
    assert np.all(draws == np.round(draws)) and draws.min() >= 0
    assert abs(draws.mean() - lam) < 5 * math.sqrt(lam / n)
    assert abs(draws.var(ddof=1) - lam) < 5 * math.sqrt((lam + 2 * lam ** 2) / n)
    assert _poisson_fit_p_value(draws, lam) > 1e-4


@pytest.mark.parametrize("lam", [10.0, 24.9, 55.5])
def test_the_poisson_fit_test_rejects_a_rounded_normal(lam):
    """The test above has the power to see an approximate sampler: a million rounded normal
    draws of the same mean and variance (ISETCam's shot noise above 25 e⁻) fail it."""
    draws = np.maximum(np.rint(np.random.default_rng(3).normal(lam, math.sqrt(lam), 1_000_000)), 0)
    assert _poisson_fit_p_value(draws, lam) < 1e-6


@pytest.mark.parametrize("lam", [10.0, 123.4, 1e4, 1e7])
def test_ln_poisson_pmf_against_40_digit_arithmetic(lam):
    """ln p(k) within 1e-10 (and a few units of double rounding) of mpmath's at 40 digits, from k = 0 to ±12 σ; scipy's logpmf is no
    oracle at λ = 1e7 (k·ln λ − ln k! cancels to ~2e-8 there)."""
    mpmath.mp.dps = 40
    k = np.unique(np.concatenate([np.arange(0, 40), np.rint(lam + math.sqrt(lam) * np.linspace(-12, 12, 97))]))
    for v in k[k >= 0]:
        exact = v * mpmath.log(lam) - lam - mpmath.loggamma(v + 1)
        assert abs(kernels._ln_poisson_pmf(float(v), lam) - float(exact)) < 1e-10 + 1e-15 * abs(float(exact)), v


def test_normal_draws_follow_numpys_ziggurat_on_the_same_stream():
    n = 2_000_000
    state = kernels.sfc64_state(3)
    z = np.empty(n)
    kernels.normal_fill(z, state)
    gen = _numpy_generator(3)
    reference = gen.standard_normal(n)
    # the tables are computed here rather than copied: equal to numpy's to the last few bits
    np.testing.assert_allclose(z, reference, rtol=0, atol=1e-13)
    np.testing.assert_array_equal(state, _state(gen))           # every draw took the same branch
    assert np.sum(np.abs(z) > kernels._ZIG_R) > 100             # the tail was sampled


def test_ziggurat_layers_have_equal_area():
    """Each layer of the ziggurat holds the same area v under exp(−x²/2) (its defining property):
    the layer out to x_{i+1} lies between heights f(x_{i+1}) and f(x_i)."""
    x = kernels.ZIG_W[1:] * kernels._MANTISSA                   # right edges x_1 < … < x_255 = R
    f = np.exp(-0.5 * x ** 2)
    np.testing.assert_allclose(x[1:] * (f[:-1] - f[1:]), kernels._ZIG_V, rtol=1e-9)
    np.testing.assert_allclose(kernels.ZIG_F[1:], f, rtol=1e-15)


def _numpy_read_out(rate, t, p: SensorParams, seed, a, b):
    """The documented read-out in plain numpy, drawing from the kernel's two streams."""
    e = rate * np.float32(t)
    e += np.float32(p.dark_current_e_per_s) * np.float32(t)
    cap = expose.SATURATION_CAP * (p.voltage_swing_V + abs(p.analog_offset_V)) / (
        p.conversion_gain_V_per_e * p.analog_gain)
    e = np.minimum(e, np.float32(cap))
    counts = np.empty(e.shape)                                    # the Poisson draws: tested above
    shot_stream = kernels.sfc64_state([seed, 0])
    for row, out in zip(e, counts):                               # drawn row by row, as the read-out does
        kernels.poisson_fill(row, out, shot_stream)
    e = counts.astype(np.float32)
    v = e * np.float32(p.conversion_gain_V_per_e)
    z = _numpy_generator([seed, 1]).standard_normal(rate.size).astype(np.float32).reshape(rate.shape)
    v += z * np.float32(p.read_noise_V)
    v = np.clip(v * a + b, 0, np.float32(p.voltage_swing_V))
    dn = np.clip(np.rint(v * np.float32(1 / p.lsb_V)), 0, np.float32(p.max_dn))
    return e, v, dn


def test_a_frame_equals_numpy_with_the_same_streams():
    p = SensorParams(rows=60, cols=80, prnu_sigma_pct=1.0, dsnu_sigma_V=1e-3, dark_voltage_V_per_s=5e-3)
    rate = np.random.default_rng(4).uniform(0, 1.5e6, (60, 80)).astype(np.float32)
    rate[:5] = 0.0                                                # dark rows: dark current only
    t = 0.01
    rng = np.random.default_rng(9)
    image = signal_rate_to_sensor_image(rate, p, t, rng)
    seeds = np.random.default_rng(9).integers(0, 2 ** 63, size=pixel_threads.BLOCKS)
    a, b = expose.fixed_patterns(p)
    for seed, rows in zip(seeds, pixel_threads.row_blocks(p.rows)):
        e, v, dn = _numpy_read_out(rate[rows], t, p, int(seed), a[rows], b[rows])
        np.testing.assert_array_equal(image.electrons[rows], e)
        np.testing.assert_allclose(image.volts[rows], v, rtol=1e-6, atol=1e-9)
        assert np.mean(image.dn[rows] != dn) < 1e-3               # a DN may round the other way
    assert image.dn.max() == p.max_dn and image.dn[:5].mean() < 5  # clipped and dark pixels both present


def test_a_frame_does_not_depend_on_the_threads(monkeypatch):
    monkeypatch.setenv(THREAD_BUDGET_ENV, "2")
    if pixel_threads.thread_count() < 2:
        pytest.skip("one core: nothing runs in threads")
    p = SensorParams(rows=300, cols=300)
    rate = np.full((300, 300), 2e5, np.float32)
    threaded = signal_rate_to_sensor_image(rate, p, 0.01, np.random.default_rng(5))
    monkeypatch.setattr(pixel_threads, "PARALLEL_MIN_PIXELS", 10 ** 9)
    serial = signal_rate_to_sensor_image(rate, p, 0.01, np.random.default_rng(5))
    np.testing.assert_array_equal(threaded.dn, serial.dn)
    np.testing.assert_array_equal(threaded.electrons, serial.electrons)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, -1.0])
@pytest.mark.parametrize("shape", [(4, 6), (300, 300)])          # one block in one thread; blocks in threads
def test_a_rate_that_is_not_finite_or_is_negative_is_refused(bad, shape):
    from workbench.errors import InvalidValueError
    from workbench.sensor import resolve_exposure
    p = SensorParams(rows=shape[0], cols=shape[1])
    rate = np.full(shape, 1e5, np.float32)
    rate[-1, -1] = bad
    for exposure in (0.01, resolve_exposure(rate, p)):       # auto-exposure of such rates is NaN or Inf
        with pytest.raises(InvalidValueError, match="finite and ≥ 0"):
            signal_rate_to_sensor_image(rate, p, exposure, np.random.default_rng(0))


def test_auto_exposures_kernels_match_numpy():
    rate = np.random.default_rng(3).lognormal(8, 3, 100_003).astype(np.float32)
    out = np.empty_like(rate)
    kernels.scale_rates(rate, np.float32(37.5), np.float32(2.7e-5), out)
    np.testing.assert_array_equal(out, (rate + np.float32(37.5)) * np.float32(2.7e-5))     # float32 steps
    assert kernels.mean_f64(out) == pytest.approx(out.mean(dtype=np.float64), rel=1e-13)
    assert math.isnan(kernels.mean_f64(out[:0]))


def test_poisson_draws_of_a_run_that_mixes_small_and_large_means():
    """Within a chunk the multiplication method's uniforms and PD's candidates interleave in the
    stream, and PD's leftovers draw after the chunk: both kinds of pixel still follow Poisson."""
    n = 1_000_000
    lam = np.where(np.arange(n) % 3 == 0, 3.3, 55.5)
    draws = np.empty(n)
    kernels.poisson_fill(lam, draws, kernels.sfc64_state([12, 0]))
    for mean in (3.3, 55.5):
        subset = draws[lam == mean]
        assert abs(subset.mean() - mean) < 5 * math.sqrt(mean / subset.size)
        assert _poisson_fit_p_value(subset, mean) > 1e-4

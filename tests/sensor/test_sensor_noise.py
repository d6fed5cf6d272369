"""Noise, fixed patterns, clipping and quantisation of one exposure; determinism; hard cases."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from workbench.sensor import (fixed_patterns, irradiance_to_sensor_image, irradiance_to_signal_rate,
                              signal_rate_to_sensor_image)

from sensor_helpers import WL16, make_params, uniform_oi


@pytest.mark.parametrize("mean_e", [0.7, 5.0, 24.0])
def test_shot_noise_is_poisson_at_low_counts(mean_e):
    """Counts follow Poisson(λ) exactly (chi-square on the histogram), mean and variance λ.

    300×300 pixels uses the threaded row-block path. Tolerances: 5 standard errors,
    SE(mean) = √(λ/N), SE(var) = √((λ + 2λ²)/N)."""
    p = make_params(rows=300, cols=300, noise_flag=1, bit_depth=0, cfa_pattern="MONO")
    img = signal_rate_to_sensor_image(np.full((300, 300), mean_e, dtype=np.float32), p, 1.0, np.random.default_rng(11))
    n = img.electrons.ravel().astype(np.int64)
    assert np.all(img.electrons == np.round(img.electrons))
    size = n.size
    assert abs(n.mean() - mean_e) < 5 * np.sqrt(mean_e / size)
    assert abs(n.var(ddof=1) - mean_e) < 5 * np.sqrt((mean_e + 2 * mean_e ** 2) / size)
    k_max = int(stats.poisson.ppf(1 - 1e-4, mean_e))
    observed = np.bincount(np.minimum(n, k_max), minlength=k_max + 1)
    pmf = stats.poisson.pmf(np.arange(k_max + 1), mean_e)
    pmf[-1] = stats.poisson.sf(k_max - 1, mean_e)
    keep = pmf * size >= 5                                           # chi-square needs ≥ 5 expected
    expected = np.append(pmf[keep] * size, pmf[~keep].sum() * size)
    obs = np.append(observed[keep], observed[~keep].sum())
    if expected[-1] == 0:
        expected, obs = expected[:-1], obs[:-1]
    assert stats.chisquare(obs, expected * obs.sum() / expected.sum()).pvalue > 1e-3


def test_read_noise_and_dark_current():
    p = make_params(rows=200, cols=200, bit_depth=0, analog_offset_V=0.5, dark_voltage_V_per_s=0.01,
                    read_noise_V=2e-3, cfa_pattern="MONO")
    dark = signal_rate_to_sensor_image(np.zeros((200, 200), np.float32), p, 0.0, np.random.default_rng(1))
    assert dark.volts.std() == pytest.approx(2e-3, rel=0.03)          # SE of σ: 1/√(2N) = 0.35 %
    assert dark.volts.mean() == pytest.approx(0.5, abs=1e-4)
    long = signal_rate_to_sensor_image(np.zeros((200, 200), np.float32), p, 2.0, np.random.default_rng(2))
    dark_e = 0.01 * 2.0 / 1e-4                                        # 200 e⁻
    assert long.electrons.mean() == pytest.approx(dark_e, rel=0.01)
    assert long.volts.var() == pytest.approx(dark_e * 1e-8 + 4e-6, rel=0.05)


def test_fixed_patterns_follow_the_sensor_seed_and_stay_put():
    p = make_params(rows=64, cols=80, prnu_sigma_pct=2.0, read_noise_V=0.0, dark_voltage_V_per_s=0.0,
                    bit_depth=0, column_fpn_gain_sigma_pct=1.0)
    a, b = fixed_patterns(p)
    assert np.std(a) == pytest.approx(np.hypot(0.02, 0.01), rel=0.15) and np.all(b == 0)
    rate = np.full((64, 80), 2e5, np.float32)
    for seed in (1, 2):                                               # two frames, same sensor
        img = signal_rate_to_sensor_image(rate, p, 0.01, np.random.default_rng(seed))
        np.testing.assert_allclose(img.volts / (img.electrons * 1e-4), a, rtol=1e-5)
    other = make_params(rows=64, cols=80, prnu_sigma_pct=2.0, column_fpn_gain_sigma_pct=1.0, seed=9)
    assert not np.allclose(fixed_patterns(other)[0], a)
    cols_only = make_params(rows=64, cols=80, column_fpn_offset_sigma_V=1e-3, dsnu_sigma_V=0.0)
    b_cols = fixed_patterns(cols_only)[1]
    assert np.all(b_cols == b_cols[0]) and np.std(b_cols[0]) == pytest.approx(1e-3, rel=0.3)


def test_gain_offset_clip_and_quantise():
    p = make_params(rows=32, cols=32, noise_flag=0, analog_gain=2.0, analog_offset_V=0.01, bit_depth=8)
    rate = np.linspace(0, 1e6, 32 * 32, dtype=np.float32).reshape(32, 32)
    img = signal_rate_to_sensor_image(rate, p, 0.01)
    expected_v = np.clip(rate * 0.01 * 1e-4 * 2.0 + 0.01, 0, 1.0)
    np.testing.assert_allclose(img.volts, expected_v, rtol=1e-5, atol=1e-7)
    np.testing.assert_array_equal(img.dn, np.clip(np.rint(img.volts * 256), 0, 255))
    assert img.dn.max() == 255 and img.max_dn == 255


def test_determinism_from_a_seed():
    p = make_params(rows=240, cols=320, prnu_sigma_pct=1.0, dsnu_sigma_V=1e-3)
    oi = uniform_oi(p, 3e14, WL16)
    a = irradiance_to_sensor_image(oi, p)
    b = irradiance_to_sensor_image(oi, p)
    c = irradiance_to_sensor_image(oi, p, seed=5)
    np.testing.assert_array_equal(a.dn, b.dn)
    np.testing.assert_array_equal(a.electrons, b.electrons)
    assert not np.array_equal(a.electrons, c.electrons)


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (3, 5), (5, 2)])
@pytest.mark.parametrize("pattern", ["GRBG", "RCCC", "RGBW", "MONO"])
def test_tiny_and_odd_sensors(shape, pattern):
    p = make_params(rows=shape[0], cols=shape[1], cfa_pattern=pattern)
    img = irradiance_to_sensor_image(uniform_oi(p, 1e15, WL16), p)
    assert img.dn.shape == shape and np.isfinite(img.dn).all() and np.isfinite(img.volts).all()
    assert img.channel_mask(0).shape == shape


@pytest.mark.parametrize("flag", [-1, 0, 1, 2])
def test_zero_saturating_and_hdr_exposures_stay_finite(flag):
    p = make_params(rows=40, cols=48, noise_flag=flag, bit_depth=10, prnu_sigma_pct=1.0)
    oi = uniform_oi(p, 1e12, WL16)
    oi.irradiance_photons[:20] *= 1e6                                # 10⁶ : 1
    oi.irradiance_photons[5:8, 5:8] = 1e30                           # the sun in view
    rate = irradiance_to_signal_rate(oi, p)
    for t in (0.0, 1e-3, 10.0):
        img = signal_rate_to_sensor_image(rate, p, t)
        for arr in (img.electrons, img.volts, img.dn):
            assert np.isfinite(arr).all() and arr.dtype == np.float32
        assert img.dn.min() >= 0 and img.dn.max() <= 1023
        if flag >= 0:
            assert img.volts.max() <= 1.0
        if t == 0.0 and flag >= 0:
            assert img.dn.max() <= 10                                # read noise only
        if t == 10.0:
            assert np.all(img.dn[5:8, 5:8] == 1023)


def _frame_sum(seed: int) -> float:
    p = make_params(rows=300, cols=300, bit_depth=0)
    return float(signal_rate_to_sensor_image(np.full((300, 300), 1e5, np.float32), p, 0.01, np.random.default_rng(seed)).volts.sum())


def test_threaded_expose_works_in_a_forked_worker():
    """The row-block threads are re-created in a forked child (a process pool must not hang)."""
    import multiprocessing
    here = _frame_sum(4)                                              # parent starts its threads
    with multiprocessing.get_context("fork").Pool(1) as pool:
        assert pool.apply_async(_frame_sum, (4,)).get(timeout=60) == here


@pytest.mark.parametrize("bad", [np.nan, np.inf, -1.0])
def test_bad_signal_rate_is_refused(bad):
    p = make_params(rows=4, cols=4)
    rate = np.ones((4, 4), np.float32)
    rate[2, 2] = bad
    with pytest.raises(ValueError, match="signal rate"):
        signal_rate_to_sensor_image(rate, p, 0.01)
    with pytest.raises(ValueError, match="4×4"):
        signal_rate_to_sensor_image(np.ones((3, 4), np.float32), p, 0.01)


@settings(max_examples=30, deadline=None)
@given(rows=st.integers(1, 9), cols=st.integers(1, 9), flag=st.sampled_from([-1, 0, 1, 2]),
       bits=st.sampled_from([0, 1, 8, 12, 24]), gain=st.floats(0.01, 100.0), offset_frac=st.floats(-0.9, 0.9),
       exposure_s=st.floats(0.0, 3600.0), log_rate=st.floats(-3.0, 20.0), prnu=st.floats(0.0, 50.0))
def test_any_exposure_stays_finite_and_in_range(rows, cols, flag, bits, gain, offset_frac, exposure_s,
                                               log_rate, prnu):
    p = make_params(rows=rows, cols=cols, noise_flag=flag, bit_depth=bits, analog_gain=gain,
                    analog_offset_V=offset_frac, prnu_sigma_pct=prnu, dsnu_sigma_V=1e-3)
    rate = np.full((rows, cols), 10.0 ** log_rate, np.float32)
    img = signal_rate_to_sensor_image(rate, p, exposure_s, np.random.default_rng(0))
    for arr in (img.electrons, img.volts, img.dn):
        assert np.isfinite(arr).all()
    if bits or flag >= 0:                                            # ideal analog volts are unclipped
        assert img.dn.min() >= 0 and img.dn.max() <= p.max_dn
    if flag >= 0:
        assert img.volts.min() >= 0 and img.volts.max() <= p.voltage_swing_V

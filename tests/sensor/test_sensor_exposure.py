"""Auto-exposure methods, EV bias and per-CFA exposure."""
from __future__ import annotations

import numpy as np
import pytest

from workbench.sensor import (auto_exposure, irradiance_to_sensor_image, irradiance_to_signal_rate,
                              signal_rate_to_sensor_image)
from workbench.spectra import macbeth_reflectances

from sensor_helpers import WL16, make_params, uniform_oi


def _chart_rate(p):
    """A Macbeth-like rate image: each 8-pixel block one patch (equal-energy light)."""
    refl = macbeth_reflectances(WL16)                                # (24, Nλ)
    idx = (np.arange(p.rows)[:, None] // 8 * 7 + np.arange(p.cols)[None, :] // 8) % 24
    oi = uniform_oi(p, 1e15, WL16)
    oi.irradiance_photons *= refl[idx].astype(np.float32)
    return oi, irradiance_to_signal_rate(oi, p)


def _ramp_oi(p):
    """Equal-energy light with a gentle left-to-right ramp (0.6–1.4): nothing clips at mean 0.4."""
    oi = uniform_oi(p, 1e15, WL16)
    oi.irradiance_photons *= np.linspace(0.6, 1.4, p.cols, dtype=np.float32)[None, :, None]
    return oi


def test_mean_method_at_0_4_gives_0_4_of_the_swing():
    for swing, offset, gain in ((1.0, 0.0, 1.0), (2.8, 0.05, 2.0)):
        p = make_params(rows=48, cols=64, noise_flag=0, bit_depth=0, auto_exposure_method="mean",
                        auto_exposure_level=0.4, voltage_swing_V=swing, analog_offset_V=offset, analog_gain=gain)
        img = irradiance_to_sensor_image(_ramp_oi(p), p)
        assert img.volts.max() < swing                               # no clipping: the oracle holds
        assert img.volts.mean() == pytest.approx(0.4 * swing, rel=1e-4)


def test_paper_exposure_lands_near_dn_102():
    """Paper's experiment: 'mean' at 0.4 of 1 V on the Table-1 pixel → 4000 e⁻ ≈ DN 102 (8 bit)."""
    p = make_params(rows=96, cols=128)
    img = irradiance_to_sensor_image(_ramp_oi(p), p)
    assert img.dn.mean() == pytest.approx(102.4, abs=1.0)


def test_ev_bias_doubles_the_exposure_per_stop():
    p = make_params(rows=16, cols=16)
    _, rate = _chart_rate(p)
    t0 = auto_exposure(rate, p)
    for ev in (-4, -2, -1, 1, 2, 4):
        assert auto_exposure(rate, make_params(rows=16, cols=16, ev_bias=ev)) == pytest.approx(t0 * 2.0 ** ev)
    fixed = make_params(rows=16, cols=16, exposure_s=0.01, ev_bias=2)
    assert irradiance_to_sensor_image(uniform_oi(fixed, 1e14, WL16), fixed).exposure_s == pytest.approx(0.04)


def test_brightest_and_percentile_methods():
    p = make_params(rows=48, cols=64, noise_flag=0, bit_depth=0, auto_exposure_method="brightest",
                    auto_exposure_level=0.95)
    oi, rate = _chart_rate(p)
    assert irradiance_to_sensor_image(oi, p).volts.max() == pytest.approx(0.95, rel=1e-4)
    q = make_params(rows=48, cols=64, noise_flag=0, bit_depth=0, auto_exposure_method="percentile",
                    auto_exposure_level=0.9)
    img = irradiance_to_sensor_image(oi, q)
    assert np.mean(img.volts >= 1.0 - 1e-6) == pytest.approx(0.1, abs=0.02)


def test_per_cfa_exposure():
    p = make_params(rows=48, cols=64, noise_flag=0, bit_depth=0, cfa_pattern="RGGB",
                    auto_exposure_method="cfa", auto_exposure_level=0.8)
    oi, rate = _chart_rate(p)
    t = auto_exposure(rate, p)
    assert t.shape == (2, 2)
    img = irradiance_to_sensor_image(oi, p)
    for i in range(2):
        for j in range(2):
            assert img.volts[i::2, j::2].max() == pytest.approx(0.8, rel=1e-4)   # each position's max
            assert t[i, j] == pytest.approx(0.8 / (rate[i::2, j::2].max() * 1e-4), rel=1e-5)
    np.testing.assert_allclose(img.exposure_s, t)
    manual = signal_rate_to_sensor_image(rate, p, [[0.01, 0.02], [0.03, 0.04]])
    np.testing.assert_allclose(manual.electrons[1::2, 0::2], rate[1::2, 0::2] * 0.03, rtol=1e-5)
    with pytest.raises(ValueError, match="tile shape"):
        signal_rate_to_sensor_image(rate, p, np.ones((3, 3)))


def test_dark_scene_and_unreachable_target():
    p = make_params(rows=8, cols=8, noise_flag=0)
    assert auto_exposure(np.zeros((8, 8), np.float32), p) == p.max_exposure_s
    off = make_params(rows=8, cols=8, analog_offset_V=0.5, auto_exposure_level=0.4)
    with pytest.raises(ValueError, match="analog offset"):
        auto_exposure(np.ones((8, 8), np.float32), off)

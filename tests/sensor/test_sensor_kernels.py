"""The compiled sensor noise against numpy: the same SFC64 stream must give numpy's own Poisson
draws (bit for bit) and normal draws, and a block read-out must equal a numpy implementation of
the documented order of operations."""
import math

import numpy as np
import pytest

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


def test_poisson_draws_equal_numpys_on_the_same_stream():
    rng = np.random.default_rng(0)
    means = np.concatenate([
        [0.0, 1e-300, 1e-6, 9.999999, 10.0, 10.000001, 1e7],         # edges: zero, the method switch, the cap
        rng.uniform(0, 12, 300_000),                                   # multiplication method and the switch
        rng.uniform(10, 20_000, 600_000),                              # transformed rejection, ln k! from the table
        10 ** rng.uniform(-3, 7, 100_000),                             # every scale, ln k! computed above the table
    ])
    for dtype in (np.float64, np.float32):
        lam = means.astype(dtype)
        state = kernels.sfc64_state([7, 1])
        out = np.empty(lam.size)
        kernels.poisson_fill(lam, out, state)
        gen = _numpy_generator([7, 1])
        np.testing.assert_array_equal(out, gen.poisson(lam))
        np.testing.assert_array_equal(state, _state(gen))      # the stream continues where numpy's does


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


@pytest.mark.parametrize("x", [1.0, 2.0, 3.0, 6.0, 7.0, 8.5, 100.0, 16_385.0, 1e6, 1e9])
def test_ln_gamma_against_the_standard_library(x):
    assert kernels._ln_gamma(x) == pytest.approx(math.lgamma(x), rel=1e-14, abs=1e-14)


def test_the_log_factorial_table_holds_ln_k_factorial():
    k = np.arange(kernels.LN_FACTORIAL_TABLE_SIZE)
    expected = np.array([math.lgamma(v + 1.0) for v in k])
    np.testing.assert_allclose(kernels.LN_FACTORIALS, expected, rtol=1e-14, atol=1e-14)


def _numpy_read_out(rate, t, p: SensorParams, seed, a, b):
    """The documented read-out in plain numpy, drawing from the kernel's two streams."""
    e = rate * np.float32(t)
    e += np.float32(p.dark_current_e_per_s) * np.float32(t)
    cap = expose.SATURATION_CAP * (p.voltage_swing_V + abs(p.analog_offset_V)) / (
        p.conversion_gain_V_per_e * p.analog_gain)
    e = np.minimum(e, np.float32(cap))
    e = _numpy_generator([seed, 0]).poisson(e).astype(np.float32)
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

"""The read-out's exact statistics against the simulator itself (Monte Carlo of flat fields) and
against the closed form where the closed form holds."""
import numpy as np
import pytest

from workbench.project import load_project
from workbench.sensor import signal_rate_to_sensor_image
from workbench.sensor.readout_stats import code_distribution, dn_to_electrons, exact_snr

PAPER = load_project("paper_camera").sensor
EXPOSURE_S = 1e-3


@pytest.mark.parametrize("bits", [8, 10, 12])
def test_exact_snr_equals_the_simulated_read_out_from_10_to_10000_electrons(bits):
    """8 bits: an LSB of 39 e⁻ against a read noise of 10 e⁻, where the closed form is off by up to 31 %."""
    sensor = PAPER.updated(bit_depth=bits, rows=256, cols=256)
    rng = np.random.default_rng(bits)
    for n in (10, 30, 100, 300, 1000, 3000):
        image = signal_rate_to_sensor_image(np.full((256, 256), n / EXPOSURE_S, np.float32), sensor, EXPOSURE_S, rng)
        e = dn_to_electrons(image.dn, sensor)
        assert float(exact_snr(n, sensor, EXPOSURE_S)) == pytest.approx(e.mean() / e.std(), rel=0.015), (bits, n)
        codes, p = code_distribution(n, sensor, EXPOSURE_S)
        assert p.sum() == pytest.approx(1.0) and (p >= 0).all()
        dn = np.asarray(image.dn, np.float64)
        assert p @ codes == pytest.approx(dn.mean(), abs=4 * dn.std() / 256 + 1e-9)


def test_where_quantisation_and_clipping_vanish_the_exact_snr_is_the_closed_form():
    from workbench.metrics.noise import snr_model
    # LSB 1.5 e⁻, read noise 10 e⁻, full well 100,000 e⁻, a black level of 1,000 e⁻ (nothing clips at 0)
    fine = PAPER.updated(bit_depth=16, conversion_gain_uV_per_e=10.0, read_noise_V=1e-4, analog_offset_V=0.01,
                         dark_voltage_V_per_s=0.0)     # (dark electrons would count in the measured mean)
    for n in (50.0, 500.0, 5000.0):
        assert float(exact_snr(n, fine, EXPOSURE_S)) == pytest.approx(float(snr_model(n, fine, EXPOSURE_S)), rel=2e-3)
    coarse = PAPER.updated(bit_depth=8)
    assert float(exact_snr(10.0, coarse, EXPOSURE_S)) < 0.8 * float(snr_model(10.0, coarse, EXPOSURE_S))


def test_without_read_noise_the_code_is_the_rounded_poisson_count():
    sensor = PAPER.updated(bit_depth=16, read_noise_V=0.0, dark_voltage_V_per_s=0.0, voltage_swing_V=65536 * 100e-6)
    codes, p = code_distribution(4.0, sensor, 0.0)                 # LSB = 1 e⁻ exactly: code k ⇔ k electrons
    from scipy import stats
    np.testing.assert_allclose(p[:12], stats.poisson.pmf(codes[:12], 4.0), atol=1e-12)


def test_the_noise_equivalent_signal_is_where_the_exact_snr_first_reaches_1():
    from workbench.metrics.frame import noise_equivalent_e
    sensor = PAPER.updated(bit_depth=8)
    n1 = noise_equivalent_e(lambda n: float(exact_snr(n, sensor, 0.0)))
    assert float(exact_snr(n1, sensor, 0.0)) == pytest.approx(1.0, abs=1e-6)
    assert all(float(exact_snr(n, sensor, 0.0)) < 1.0 for n in np.geomspace(1e-3, 0.999 * n1, 40))
    assert noise_equivalent_e(lambda n: 0.5) is None                     # never reaches 1: no figure

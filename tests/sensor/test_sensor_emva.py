"""EMVA 1288 photon transfer on simulated flat fields gives back the configured sensor."""
from __future__ import annotations

import json

import numpy as np
import pytest

from workbench.sensor.emva import characterize, plot_photon_transfer

from sensor_helpers import make_params

CHECKED = ("conversion_gain_uV_per_e", "read_noise_e", "dark_current_e_per_s")


@pytest.mark.parametrize("preset,changes", [
    ("paper_table1", {"bit_depth": 0}),                               # analog volts
    ("paper_table1", {"bit_depth": 16, "prnu_sigma_pct": 1.0, "dsnu_sigma_V": 2e-3}),
    ("auto_rccc", {"bit_depth": 14, "analog_gain": 2.0, "dark_voltage_V_per_s": 5e-3}),
])
def test_photon_transfer_recovers_the_configuration(preset, changes):
    p = make_params(preset, **changes)
    r = characterize(p, seed=3)
    conf = r["configured"]
    for key in CHECKED:
        assert r[key] == pytest.approx(conf[key], rel=0.03), key
    if p.bit_depth:
        assert r["conversion_gain_DN_per_e"] == pytest.approx(conf["conversion_gain_DN_per_e"], rel=0.03)
    # EMVA's saturation point (maximum temporal variance) sits ~3 σ_shot below the hard clip
    assert r["saturation_capacity_e"] == pytest.approx(conf["saturation_capacity_e"], rel=0.06)
    assert r["saturation_capacity_e"] < conf["saturation_capacity_e"]
    assert r["quantum_efficiency"] == pytest.approx(conf["quantum_efficiency"], rel=0.03)
    expected_dr = 20 * np.log10(conf["saturation_capacity_e"] / (conf["read_noise_e"] + 0.5))
    assert r["dynamic_range_dB"] == pytest.approx(expected_dr, abs=0.6)
    json.dumps(r)                                                     # plain data


def test_fixed_pattern_noise_is_measured():
    p = make_params(bit_depth=0, prnu_sigma_pct=2.0, dsnu_sigma_V=3e-3)
    r = characterize(p, seed=1)
    assert r["prnu_pct"] == pytest.approx(2.0, rel=0.1)
    assert r["dsnu_e"] == pytest.approx(30.0, rel=0.1)


def test_noise_free_sensor_is_refused():
    with pytest.raises(ValueError, match="noise_flag"):
        characterize(make_params(noise_flag=0))


def test_plot_is_written(tmp_path):
    r = characterize(make_params(bit_depth=12), seed=0, size_px=32, n_levels=20)
    out = plot_photon_transfer(r, tmp_path / "ptc.png")
    assert out.stat().st_size > 10_000 and out.read_bytes()[:4] == b"\x89PNG"


def test_a_read_noise_hidden_by_an_8_bit_adc_is_measured_through_a_finer_one():
    """At 8 bits (LSB 39 e⁻ with the paper's swing and gain) the dark noise is below one code: the
    read noise was reported as '≥ 0 e⁻'; now it is measured through a 16-bit ADC and says so."""
    p = make_params(bit_depth=8, read_noise_V=1e-3)                 # 10 e⁻ at 100 µV/e⁻
    r = characterize(p, seed=0, size_px=64, n_levels=20)
    assert r["adc_step_e"] == pytest.approx(1.0 / 256 / 100e-6, rel=0.05) and r["read_noise_bits"] == 16
    assert r["read_noise_e"] == pytest.approx(r["configured"]["read_noise_e"], rel=0.08)
    assert not r["read_noise_is_lower_bound"] and "16-bit ADC" in r["notes"][0]
    from workbench.gui.editors.sensor import emva_summary
    assert "≥" not in emva_summary(r) and "16-bit" in emva_summary(r)

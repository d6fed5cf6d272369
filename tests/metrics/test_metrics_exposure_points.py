"""Where the camera metrics read their signal: an edge the design's exposure clips is re-exposed
unclipped (a clipped edge lifted raw G's MTF50 to 0.42 cy/px, above the 0.25 that diffraction at
f/8 and the pixel allow); the headline SNR is measured at 10 % of the electrons at saturation (not
at whichever exposure of a factor-of-2 series lands nearest: 323 e⁻ for a design capped at 20 ms),
and the dynamic range counts the analog gain, as sensor_dynamic_range does."""
import math

import pytest

from workbench.project import load_project


def _edge(**sensor):
    p = load_project("slanted_edge_diffraction_f8")
    return p.updated(sensor=p.sensor.updated(rows=128, cols=128, noise_flag=0, **sensor))


def test_an_edge_the_exposure_clips_is_re_exposed_and_measures_the_closed_form():
    from workbench.metrics.frame import system_mtf
    for ev, clipped in ((0.0, False), (1.0, True)):
        rows = {r["plane"]: r for r in system_mtf(_edge(ev_bias=ev))}
        g = rows["raw G"]
        assert g["exposure"]["re_exposed"] is clipped, ev
        assert (g["exposure"]["clipped_pct_at_project_exposure"] > 40) is clipped      # EV +1: about half clips
        assert g["mtf50_cy_px"] == pytest.approx(g["model_mtf50_cy_px"], abs=0.01), ev  # was 0.418 against 0.249
        assert ("re-exposed" in g["exposure"]["note"]) is clipped
        assert rows["sRGB luminance"]["exposure"] == g["exposure"]


@pytest.fixture(scope="module")
def low_light_gain_4():
    """A 64×64 paper-style design at analog gain 4 whose auto-exposure is capped at 20 ms."""
    from workbench.metrics.frame import camera_metrics
    p = load_project("slanted_edge_diffraction_f8")
    p = p.updated(sensor=p.sensor.updated(rows=64, cols=64, analog_gain=4.0, max_exposure_s=0.02))
    return p, camera_metrics(p, noise_draws=0)


def test_the_headline_snr_is_read_at_a_tenth_of_saturation(low_light_gain_4):
    from workbench.metrics.noise import snr_model
    from workbench.sensor.snr import sensor_dynamic_range
    p, m = low_light_gain_4
    saturation_e = sensor_dynamic_range(p.sensor)["saturation_e"]
    assert saturation_e == pytest.approx(p.sensor.full_well_e / 4, rel=0.01)             # gain 4: a quarter
    rows = m["snr_at_saturation_share"]
    assert {r["channel"] for r in rows} == {"R", "G", "B"}
    for r in rows:
        assert r["mean_e"] == pytest.approx(0.1 * saturation_e, rel=0.03)                # measured there
        assert r["target_e"] == pytest.approx(0.1 * saturation_e)
    expected_dB = 20 * math.log10(float(snr_model(0.1 * saturation_e, p.sensor, 0.0)))    # shot + read + codes
    assert m["summary"]["snr_at_10pct_full_well_dB"] == pytest.approx(expected_dB, abs=0.5)


def test_the_dynamic_range_counts_the_analog_gain(low_light_gain_4):
    from workbench.sensor.snr import sensor_dynamic_range
    p, m = low_light_gain_4
    s = m["summary"]
    assert s["saturation_e"] == pytest.approx(sensor_dynamic_range(p.sensor)["saturation_e"])
    assert s["dynamic_range_dB"] == pytest.approx(20 * math.log10(s["saturation_e"] / p.sensor.read_noise_e))
    assert s["dynamic_range_dB"] == pytest.approx(20 * math.log10(p.sensor.full_well_e / p.sensor.read_noise_e)
                                                  - 20 * math.log10(4), abs=0.1)        # 60 dB at gain 1, 48 at 4


def test_a_sensor_too_small_for_the_edge_says_how_large_it_must_be():
    from workbench.errors import ParameterError
    from workbench.metrics.frame import system_mtf
    p = load_project("slanted_edge_diffraction_f8")
    with pytest.raises(ParameterError, match=r"sensor\.rows.*at least 32"):      # was: the e-SFR's (8, 8) region
        system_mtf(p.updated(sensor=p.sensor.updated(rows=16, cols=64)))

"""Night and tunnel frames through the pipeline with the auto_rccc sensor (issue 8): the sensor
clips where a linear sensor of its full well and ADC must, and the report states the scene's
dynamic range.

Oracles, independent of the sensor code: a pixel's electrons computed here from the optical
image's irradiance (photons/s/m²/nm, on the pixel grid), the channel QE curves, the pixel's area
and fill factor and the exposure; the saturation level from the part's documented numbers
(MT9V024-like: 2.8 V swing at 110 µV/e⁻ = 25,455 e⁻ full well, volts × the analog gain) and
the ADC's codes (a code is rint(V / LSB) with LSB = swing / 2^bits, so the top code 2^bits − 1
is reached from (2^bits − 1.5) LSB); luminance as 683 lm/W · Σ L_photons · hc/λ · V(λ) · Δλ."""
import json

import numpy as np
import pytest

from workbench.commands.core import stage_report
from workbench.pipeline import Pipeline
from workbench.project import load_project
from workbench.sensor import channel_qe
from workbench.spectra import luminous_efficiency

ROWS, COLS = 72, 96
FULL_WELL_E = 2.8 / 110e-6
H_PLANCK, C_LIGHT = 6.62607015e-34, 299792458.0


def _tiny(name: str):
    p = load_project(name)
    assert p.sensor.cfa_pattern == "RCCC" and p.sensor.full_well_e == pytest.approx(FULL_WELL_E)
    pitch = p.sensor.pixel_pitch_um * p.sensor.cols / COLS                 # same field of view
    return p.updated(sensor=p.sensor.updated(rows=ROWS, cols=COLS, pixel_pitch_um=pitch, noise_flag=0),
                     render=p.render.updated(spp=4, chunk_spp=4, band_count=12))


def _expected_electrons(result, sensor):
    oi = result.optical_image
    assert oi.irradiance_photons.shape[:2] == (ROWS, COLS)
    assert oi.sample_spacing_m == pytest.approx(sensor.pixel_pitch_um * 1e-6)
    wl = np.asarray(oi.wavelengths_nm)
    step_nm = np.diff(wl)
    assert np.allclose(step_nm, step_nm[0])                                # box bands: equal widths
    qe = channel_qe(sensor, wl)                                            # (Nλ, K) curves
    k = np.tile(result.sensor_image.cfa_tile, (ROWS // 2, COLS // 2))
    per_channel = oi.irradiance_photons.astype(np.float64) @ qe * step_nm[0]    # photons/s/m² → e⁻/s/m²
    rate = np.take_along_axis(per_channel, k[..., None], axis=2)[..., 0]
    area_m2 = (sensor.pixel_pitch_um * 1e-6) ** 2 * sensor.fill_factor
    return rate * area_m2 * float(np.mean(result.sensor_image.exposure_s))


def _luminance(radiance_photons, wl):
    energy = radiance_photons.astype(np.float64) * (H_PLANCK * C_LIGHT / (np.asarray(wl) * 1e-9))
    return 683.0 * energy @ (luminous_efficiency(wl) * (wl[1] - wl[0]))


@pytest.fixture(scope="module", params=["city_night", "city_tunnel"])
def pipe(request):
    pipe = Pipeline(_tiny(request.param))
    pipe.run()
    return pipe


@pytest.mark.parametrize("bits", [10, 12])
def test_clipped_pixels_are_those_past_saturation(pipe, bits):
    project = pipe.project.updated(sensor=pipe.project.sensor.updated(bit_depth=bits))
    pipe.set_project(project)
    result = pipe.run()
    img = result.sensor_image
    assert img.max_dn == 2 ** bits - 1
    electrons = _expected_electrons(result, project.sensor)
    np.testing.assert_allclose(img.electrons, electrons, rtol=1e-4, atol=1e-3)
    e_clip = FULL_WELL_E * (2 ** bits - 1.5) / 2 ** bits / project.sensor.analog_gain    # gain × volts
    clipped = img.dn >= img.max_dn
    near = np.abs(electrons / e_clip - 1) < 1e-4                           # float32 round-off
    np.testing.assert_array_equal(clipped[~near], (electrons >= e_clip)[~near])
    assert 0 < clipped.mean() < 0.5, clipped.mean()                        # lamps / the exit clip
    report = stage_report(result, project)
    assert report["fraction_clipped"] == pytest.approx(clipped.mean())
    assert report["sensor_dynamic_range"]["saturation_e"] == pytest.approx(e_clip, rel=1e-9)
    read_e = project.sensor.read_noise_V / 110e-6
    assert report["sensor_dynamic_range"]["dynamic_range_dB"] == pytest.approx(20 * np.log10(e_clip / read_e))


def test_with_noise_only_the_edge_of_saturation_is_uncertain(pipe):
    project = pipe.project.updated(sensor=pipe.project.sensor.updated(noise_flag=2))
    pipe.set_project(project)
    result = pipe.run()
    electrons = _expected_electrons(result, project.sensor)
    sigma = np.sqrt(electrons + (project.sensor.read_noise_V / 110e-6) ** 2)
    bits = project.sensor.bit_depth
    e_clip = FULL_WELL_E * (2 ** bits - 1.5) / 2 ** bits / project.sensor.analog_gain
    clipped = result.sensor_image.dn >= result.sensor_image.max_dn
    assert clipped[electrons > e_clip + 6 * sigma].all()
    assert not clipped[electrons < e_clip - 6 * sigma].any()


def test_report_states_the_scene_dynamic_range(pipe):
    pipe.set_project(pipe.project.updated(sensor=pipe.project.sensor.updated(noise_flag=0, bit_depth=10)))
    result = pipe.run()
    report = json.loads(json.dumps(stage_report(result, pipe.project)))      # as report.json holds it
    got = report["scene_dynamic_range"]
    lum = _luminance(result.scene.radiance_photons, np.asarray(result.scene.wavelengths_nm)).ravel()
    lit = lum[lum > 0]
    lo, hi = np.percentile(lit, [0.1, 99.9])
    assert got["quantity"] == "luminance (cd/m2)" and got["percentiles"] == [0.1, 99.9]
    assert got["ratio"] == pytest.approx(hi / lo, rel=1e-6)
    assert got["dB"] == pytest.approx(20 * np.log10(hi / lo), rel=1e-6)
    assert got["max_min_ratio"] == pytest.approx(lit.max() / lit.min(), rel=1e-6)
    assert got["max"] == pytest.approx(lit.max(), rel=1e-6)
    sensor_dB = report["sensor_dynamic_range"]["dynamic_range_dB"]
    assert report["scene_exceeds_sensor_range"] == (got["dB"] > sensor_dB)

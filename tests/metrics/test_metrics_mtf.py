"""The camera's MTF as ISO 12233 measures it and as its factors predict it (issue 31, items 1–2):
flat-fielded e-SFR (lens fall-off cannot lift the curve), raw CFA planes measured on their own sites
at full resolution, MTF50's bootstrap uncertainty against repeated noise draws, and the measured
system MTF of the pipeline against diffraction × pixel aperture weighted by the sensor's spectrum
(closed form computed here, independently of workbench.metrics.mtf_model)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import ndtr

from workbench.metrics.esfr import cfa_plane_nyquist_cy_px, edge_sfr, measured_mtf50, mtf50_spread


def gaussian_edge(sigma_px: float, size: int = 128, angle_deg: float = 5.0) -> np.ndarray:
    y, x = np.mgrid[0:size, 0:size] + 0.5
    t = math.tan(math.radians(angle_deg))
    d = (x - size / 2 - t * (y - size / 2)) * math.cos(math.radians(angle_deg))
    return 0.2 + 0.6 * ndtr(d / sigma_px)


def shading(size: int = 128, strength: float = 0.1) -> np.ndarray:
    """A cos⁴-like fall-off about the centre (where the edge is, as on the chart), 1 − strength in the corners."""
    y, x = np.mgrid[0:size, 0:size] + 0.5
    r2 = ((x - size / 2) ** 2 + (y - size / 2) ** 2) / size ** 2
    return 1.0 - strength * r2 / r2.max()


def test_flat_field_keeps_the_mtf_at_1_near_zero_frequency_under_lens_fall_off():
    sigma = 1.0
    shade = shading()
    image = gaussian_edge(sigma) * shade
    raw = edge_sfr(image)
    f = raw.frequency_cy_px
    assert raw.mtf[(f > 0) & (f <= 0.1)].max() > 1.005            # the old, uncorrected measurement lifts
    sfr = edge_sfr(image, flat=shade * 3.7)                        # any scale of the flat field
    assert sfr.mtf[0] == 1.0 and sfr.mtf[f <= 0.1].max() <= 1.0 + 1e-6
    closed = np.exp(-2 * (math.pi * sigma * f) ** 2)
    assert np.abs(sfr.mtf - closed)[f <= 0.5].max() < 0.01


@pytest.mark.parametrize("pattern, channel, nyquist", [("RGGB", 0, 0.25), ("RGGB", 1, 0.5), ("MONO", 0, 0.5),
                                                       ("RCCC", 1, 0.5), ("RCCC", 0, 0.25)])
def test_a_cfa_plane_is_measured_on_its_own_sites_in_full_sensor_pixels(pattern, channel, nyquist):
    from workbench.sensor.cfa import cfa_layout
    tile, _ = cfa_layout(pattern)
    assert cfa_plane_nyquist_cy_px(tile, channel) == nyquist
    sigma = 0.8
    image = gaussian_edge(sigma, size=160)
    sites = np.tile(tile, (80, 80)) == channel
    sfr = edge_sfr(image, mask=sites)
    f = sfr.frequency_cy_px
    closed = np.exp(-2 * (math.pi * sigma * f) ** 2)
    keep = f <= min(0.5, 1.6 * nyquist)
    assert np.abs(sfr.mtf - closed)[keep].max() < 0.01
    assert sfr.mtf50_cy_px == pytest.approx(math.sqrt(math.log(2) / 2) / (math.pi * sigma), rel=0.01)


def test_mtf50_bootstrap_spread_matches_the_spread_over_noise_draws():
    rng = np.random.default_rng(3)
    clean = gaussian_edge(1.0, size=96)
    draws = [clean + rng.normal(0, 0.01, clean.shape) for _ in range(30)]
    spread_over_draws = float(np.std([edge_sfr(d).mtf50_cy_px for d in draws], ddof=1))
    bootstrap = np.median([mtf50_spread(d, draws=30, seed=i) for i, d in enumerate(draws[:6])])
    assert 0.6 < bootstrap / spread_over_draws < 1.6
    assert mtf50_spread(clean) < 0.1 * spread_over_draws           # no noise: (almost) no spread


def test_mtf50_of_a_noisy_edge_is_unbiased_over_noise_draws():
    """A Gaussian edge (σ 0.8 px, closed-form MTF50 0.2342 cy/px) in a 128×256 region (the DFT samples
    the curve every 0.004 cy/px, as on the charts' 240-pixel regions) with white noise of 5 % of the
    step: MTF50's mean over 100 draws within 2 % of the closed form. The first 0.5 crossing of each
    noisy curve (the old MTF50) read 2.5–5.2 % low over seeds 0–9 (60 draws each); measured_mtf50
    0.4–1.9 % low: 0.4 % the point-sampled Gaussian's aliasing (also without noise), the rest the edge
    fit's jitter."""
    sigma = 0.8
    closed = math.sqrt(math.log(2) / 2) / (math.pi * sigma)
    y, x = np.mgrid[0:128, 0:256] + 0.5
    t = math.tan(math.radians(5.0))
    clean = 0.2 + 0.6 * ndtr((x - 128 - t * (y - 64)) * math.cos(math.radians(5.0)) / sigma)
    rng = np.random.default_rng(0)
    found = [edge_sfr(clean + rng.normal(0, 0.03, clean.shape)).mtf50_cy_px for _ in range(100)]
    assert np.mean(found) == pytest.approx(closed, rel=0.02)
    assert edge_sfr(clean).mtf50_cy_px == pytest.approx(closed, rel=0.005)


@pytest.mark.parametrize("sigma", [0.3, 0.8, 3.0])
def test_measured_mtf50_of_a_noise_free_curve_is_its_crossing(sigma):
    f = np.arange(0.0, 1.0, 0.004)
    assert measured_mtf50(f, np.exp(-2 * (math.pi * sigma * f) ** 2)) == pytest.approx(
        math.sqrt(math.log(2) / 2) / (math.pi * sigma), rel=2e-4)
    assert measured_mtf50(f, np.full(f.size, 0.9)) is None


def closed_form_raw_g(project, frequency_cy_px: np.ndarray, angle_deg: float) -> np.ndarray:
    """Diffraction OTF at the working f-number, averaged over wavelength with weights D65 photons ×
    the G channel's effective QE, times the pixel aperture's |sinc| across the edge."""
    from workbench.scene.charts import _illuminant_photons
    from workbench.sensor.cfa import cfa_layout, channel_qe
    wl = np.arange(400.0, 701.0, 10.0)
    _, names = cfa_layout(project.sensor.cfa_pattern)
    w = _illuminant_photons("D65", wl, 1.0) * channel_qe(project.sensor, wl)[:, names.index("G")]
    w = w / w.sum()
    f_m = project.optics.focal_length_mm * 1e-3
    n_w = project.optics.f_number / (1 - f_m / project.scene.distance_m)       # N · image distance / f
    nu = frequency_cy_px / (project.sensor.pixel_pitch_um * 1e-6)
    otf = 0.0
    for wt, lam in zip(w, wl * 1e-9):
        s = np.clip(nu * lam * n_w, 0, 1)
        otf = otf + wt * (2 / np.pi) * (np.arccos(s) - s * np.sqrt(1 - s * s))
    a = 1.0 if project.sensor.pixel_aperture == "microlens" else math.sqrt(project.sensor.fill_factor)
    t = math.radians(angle_deg)
    return otf * np.abs(np.sinc(a * frequency_cy_px * math.cos(t)) * np.sinc(a * frequency_cy_px * math.sin(t)))


VARIANTS = {"f8 3 µm": {}, "f4 2 µm": {"f_number": 4.0, "pixel_pitch_um": 2.0},
            "f8 3 µm photodiode FF 0.5": {"pixel_aperture": "photodiode", "fill_factor": 0.5}}


@pytest.mark.parametrize("variant", VARIANTS)
def test_measured_system_mtf_equals_optics_times_pixel_with_fall_off_on(variant):
    """slanted_edge_diffraction_f8 as saved (cos⁴ fall-off on, GRBG, 8-bit), temporal noise off:
    raw G measured within 0.01 of the closed form over 0–0.5 cy/px; MTF(0) = 1 and no point above 1
    near zero on every measured plane."""
    from workbench.metrics.frame import system_mtf
    from workbench.project import load_project
    p = load_project("slanted_edge_diffraction_f8")
    assert p.optics.off_axis == "cos4th"
    v = VARIANTS[variant]
    p = p.updated(optics=p.optics.updated(f_number=v.get("f_number", 8.0)),
                  sensor=p.sensor.updated(noise_flag=0, **{k: x for k, x in v.items() if k != "f_number"}))
    rows = {r["plane"]: r for r in system_mtf(p)}
    for r in rows.values():
        f, m = np.asarray(r["frequency_cy_px"]), np.asarray(r["mtf"])
        assert m[0] == pytest.approx(1.0) and m[f <= 0.1].max() <= 1.0 + 1e-9, r["plane"]
    g = rows["raw G"]
    f = np.asarray(g["frequency_cy_px"])
    closed = closed_form_raw_g(p, f, g["edge_angle_deg"])
    keep = f <= 0.5
    assert np.abs(np.asarray(g["mtf"]) - closed)[keep].max() < 0.01
    assert np.abs(np.asarray(g["model_mtf"]) - closed).max() < 1e-3            # the workbench's own closed form
    assert g["nyquist_cy_px"] == 0.5 and rows["raw R"]["nyquist_cy_px"] == 0.25
    assert rows["raw R"]["reliable_up_to_cy_px"] == pytest.approx(0.4)
    optics = rows["optics (model)"]
    aperture_free = closed_form_raw_g(p.updated(sensor=p.sensor.updated(pixel_aperture="microlens")),
                                      np.asarray(optics["frequency_cy_px"]), 0.0) / \
        np.abs(np.sinc(np.asarray(optics["frequency_cy_px"])))
    f_o = np.asarray(optics["frequency_cy_px"])
    assert np.abs(np.asarray(optics["mtf"]) - aperture_free)[f_o <= 0.9].max() < 1e-3   # no pixel box in it


@pytest.mark.parametrize("variant", ["f8 3 µm", "f4 2 µm"])
def test_system_mtf_with_the_projects_noise_averages_to_optics_times_pixel(variant):
    """slanted_edge_diffraction_f8 as saved (fall-off on, 8 bits, read and shot noise on), over the noise
    draws camera_metrics takes (sensor seeds seed … seed + NOISE_DRAWS): the mean MTF50 of raw G, R and B
    within 0.006 cy/px of the closed form (measured: 0.0002–0.0019, f/8 B 0.0056; the first crossing read
    f/4 2 µm raw G 0.0100 low), raw G's mean MTF at 0.25 and 0.5 cy/px within 0.01 (measured 0.0046–0.0051
    and +0.006–0.008: at 0.5 the noise floor of |DFT| lifts it)."""
    from workbench.metrics.frame import NOISE_DRAWS, ChartShots, system_mtf, uniform_chart
    from workbench.project import load_project
    p = load_project("slanted_edge_diffraction_f8")
    v = VARIANTS[variant]
    p = p.updated(optics=p.optics.updated(f_number=v.get("f_number", 8.0)),
                  sensor=p.sensor.updated(**{k: x for k, x in v.items() if k != "f_number"}))
    assert p.sensor.noise_flag == 2 and p.optics.off_axis == "cos4th"
    shots, found = ChartShots(), []
    for seed in range(p.sensor.seed, p.sensor.seed + NOISE_DRAWS + 1):
        q = p.updated(sensor=p.sensor.updated(seed=seed))
        found.append({r["plane"]: r for r in system_mtf(q, shots.run(uniform_chart(q)), shots)})
    for plane in ("raw G", "raw R", "raw B"):
        m50 = np.mean([rows[plane]["mtf50_cy_px"] for rows in found])
        assert m50 == pytest.approx(found[0][plane]["model_mtf50_cy_px"], abs=0.006), plane
    g = found[0]["raw G"]
    closed = closed_form_raw_g(p, np.array([0.25, 0.5]), g["edge_angle_deg"])
    assert np.mean([rows["raw G"]["mtf_0.25"] for rows in found]) == pytest.approx(closed[0], abs=0.01)
    assert np.mean([rows["raw G"]["mtf_nyquist"] for rows in found]) == pytest.approx(closed[1], abs=0.01)


def test_fill_factor_enters_the_mtf_only_with_the_photodiode_aperture():
    from workbench.metrics.mtf_model import pixel_mtf
    from workbench.sensor.params import SensorParams
    f = np.array([0.25, 0.5])
    lens = [pixel_mtf(SensorParams(fill_factor=ff), f) for ff in (0.5, 1.0)]
    np.testing.assert_array_equal(*lens)
    bare = [pixel_mtf(SensorParams(fill_factor=ff, pixel_aperture="photodiode"), f) for ff in (0.5, 1.0)]
    assert bare[0][1] == pytest.approx(np.sinc(0.5 * math.sqrt(0.5))) and bare[1][1] == pytest.approx(np.sinc(0.5))


def test_old_projects_keep_the_microlens_aperture_and_their_cache_keys():
    """A project saved before pixel_aperture existed validates with the microlens default, and the
    stage keys / data-set fingerprints (digests without default fields) stay as they were."""
    import json

    from workbench.project import load_project, project_from_dict
    from workbench.resource_dir import RESOURCES
    from workbench.stages.keys import digest
    data = json.loads((RESOURCES / "projects" / "slanted_edge_diffraction_f8.json").read_text())
    data["sensor"].pop("pixel_aperture", None)          # as saved before the field existed
    p = project_from_dict(data)
    assert p.sensor.pixel_aperture == "microlens" and p.sensor.aperture_width_px == 1.0
    # digests computed on the code before this change (commit 05165ea)
    assert digest(p.sensor.pixel_response) == "c5a091b4d8dc29668b6465c487942cb91ccbb77c"
    assert digest(p.sensor) == "ee6ff2c347f22998df9a58586d49bb6a20acf459"
    assert load_project("slanted_edge_diffraction_f8").sensor == p.sensor


def test_photodiode_aperture_needs_a_whole_number_of_samples_per_pixel():
    from workbench.errors import WorkbenchError
    from workbench.optics.types import OpticalImage
    from workbench.sensor.params import SensorParams
    from workbench.sensor.signal import irradiance_to_signal_rate
    sp = SensorParams(rows=8, cols=8, fill_factor=0.5, pixel_aperture="photodiode", cfa_pattern="MONO",
                      filter_file=None)
    oi = OpticalImage(np.ones((12, 12, 1), np.float32), np.array([550.0]), 3e-6 / 1.5, 1e-3, 4.0)
    with pytest.raises(WorkbenchError, match="whole number"):
        irradiance_to_signal_rate(oi, sp.pixel_response)


@pytest.mark.parametrize("folder", ["budget-standard", "isp-standard", "schedule-study/budget-batch16"])
def test_committed_standard_results_keep_their_projects_and_fingerprints(folder):
    """The committed result folders' projects load (read-only) with the microlens default, and their
    frame inputs, pixel response and sensor digest as on the code before pixel_aperture (05165ea)."""
    from pathlib import Path

    from workbench.project import load_project
    from workbench.render.city_frame import city_frame_inputs
    from workbench.stages.keys import digest
    p = load_project(Path(__file__).resolve().parents[2] / "docs" / "results" / folder / "project.json")
    assert p.sensor.pixel_aperture == "microlens"
    assert digest(city_frame_inputs(p)) == "28fb8e3a41e586190c07ced33329dc0fa59d2a88"
    assert digest(p.sensor.pixel_response) == "6d7bbf525db10cc56db5e0c9122d2d39d67c6897"
    assert digest(p.sensor) == "52003b784ae8ecb058db2a070a765b9a48786186"

"""The window renders a city once for every CFA pattern (issue 32 item 7): box bands between the
union of every pattern's band edges, summed into each pattern's own bands exactly. A Bayer → RCCC →
RCCB → Bayer edit renders nothing; data sets keep their film, frames and fingerprints."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from workbench.jobs import run_job
from workbench.pipeline import Pipeline
from workbench.project import load_project
from workbench.render.city_frame import CitySceneSession, city_scene_inputs, frame_seeds
from workbench.render.film import box_bands, box_bands_between
from workbench.render.shared_bands import (SharedBandRenderer, band_sum_matrix, own_bands, pattern_band_edges_nm,
                                           rendered_inputs, shared_bands)
from workbench.sensor.cfa import SENSOR_SPECTRAL_GRID_NM, channel_qe
from workbench.sensor.params import CFA_PATTERNS

COMMITTED = Path(__file__).resolve().parents[2] / "docs" / "results"
# dataset_fingerprint(city_detection_quick, 'float16', render_city_frame) computed with the code
# of main before this change (b8a4d2e); the committed standard results were made on it.
QUICK_FINGERPRINT = "647d93842d64fee672acfb132215c44720f02526"
# Digests of the Mitsuba film a data-set frame renders through (film_digest below), from main's code.
DATASET_FILMS = {("city_detection_quick", None): "ebba986a555dbade",
                 ("city_day_clear_sky", None): "22e4eeb524e37f7b",
                 ("city_day_clear_sky", "RCCC"): "af1a689cf142a704"}


def tiny_city(spp=4, cfa="GRBG"):
    p = load_project("city_paper_camera")
    return p.updated(sensor=p.sensor.updated(rows=36, cols=48, cfa_pattern=cfa), render=p.render.updated(spp=spp),
                     city=p.city.updated(blocks_x=1, blocks_y=1, n_pedestrians=4, n_trees=4, n_lamps=4,
                                         n_benches=2, n_mailboxes=1))


def with_cfa(project, cfa):
    return project.updated(sensor=project.sensor.updated(cfa_pattern=cfa))


def film_digest(project) -> str:
    from workbench.render.spectral import film_for
    inputs = city_scene_inputs(project)
    qe = np.asarray(channel_qe(inputs.pixels, SENSOR_SPECTRAL_GRID_NM)).T
    film = film_for(inputs.render, (SENSOR_SPECTRAL_GRID_NM, qe))
    text = (json.dumps(film.mitsuba_film(8, 6), sort_keys=True) + repr(film.output_wavelengths_nm.tolist())
            + repr(film.reconstruction.tolist()))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def test_data_sets_keep_their_fingerprint_and_film():
    """The data-set path is untouched: city_detection_quick's fingerprint is main's, the committed
    standard results' data set is the one their project makes, and the films a data-set frame
    renders through (Bayer and RCCC) are main's byte for byte."""
    from workbench.datasets.dataset import dataset_fingerprint
    from workbench.render.city_frame import render_city_frame
    assert dataset_fingerprint(load_project("city_detection_quick"), "float16", render_city_frame) == QUICK_FINGERPRINT
    folders = sorted(COMMITTED.glob("*-standard"))
    assert folders, "no committed standard results"
    for folder in folders:
        doc = json.loads((folder / "results.json").read_text())
        project = load_project(folder / "project.json")
        assert dataset_fingerprint(project, "float16", render_city_frame) == doc["dataset"]["fingerprint"], folder
    for (name, cfa), expected in DATASET_FILMS.items():
        project = load_project(name) if cfa is None else with_cfa(load_project(name), cfa)
        assert film_digest(project) == expected, (name, cfa)


def test_every_patterns_bands_are_sums_of_the_shared_bands():
    """Each pattern's own box bands are exactly sums of the shared ones: the summed responses equal
    the pattern's, so the summed integrals ∫ L s dλ are the pattern's for any spectrum."""
    project = load_project("city_day_clear_sky")
    shared = shared_bands(project)
    edges = pattern_band_edges_nm(project.sensor.pixel_response, project.render.band_count)
    assert set(edges) == set(CFA_PATTERNS)
    assert {(e[0], e[-1]) for e in edges.values()} == {(390.0, 695.0), (385.0, 695.0)}   # Bayer, the others
    assert len(shared.edges_nm) - 1 == 32
    fine = box_bands_between(np.asarray(shared.edges_nm))
    grid = np.linspace(380.0, 700.0, 64001)
    fine_resp = np.stack([np.interp(grid, fine.wavelengths_nm, r) for r in fine.responses])
    for pattern, own_edges in edges.items():
        own = box_bands_between(own_edges)
        m = band_sum_matrix(shared.edges_nm, own_edges)
        summed = (m * np.diff(own_edges)[:, None] / np.diff(shared.edges_nm)[None, :]) @ fine_resp   # 0/1 × SRFs
        own_resp = np.stack([np.interp(grid, own.wavelengths_nm, r) for r in own.responses])
        assert np.max(np.abs(summed - own_resp)) < 1e-9, pattern
        radiance = 1e16 * (1.5 + np.sin(fine.output_wavelengths_nm / 17.0))     # band means of a spectrum
        assert np.allclose(m @ radiance, own_bands_mean(radiance, shared.edges_nm, own_edges), rtol=1e-12)


def own_bands_mean(fine_means, edges, own_edges):
    """Band means over own_edges from band means over edges, by integrating the step function."""
    cumulative = np.concatenate([[0.0], np.cumsum(fine_means * np.diff(edges))])
    at = np.interp(own_edges, edges, cumulative)
    return np.diff(at) / np.diff(own_edges)


def test_box_bands_are_box_bands_between_equal_edges():
    a, b = box_bands(390.0, 695.0, 16), box_bands_between(np.linspace(390.0, 695.0, 17))
    assert np.array_equal(a.responses, b.responses) and np.array_equal(a.wavelengths_nm, b.wavelengths_nm)
    assert np.array_equal(a.reconstruction, b.reconstruction) and a.names == b.names


def test_the_macbeth_response_per_channel_is_the_patterns_own():
    """The sensor's response per channel to the 24 Macbeth patches under D65 through the shared
    bands summed into a pattern's bands equals the response through the pattern's own bands
    (relative difference < 1e-6 in every channel and patch)."""
    from workbench import spectra
    from workbench.sensor.signal import channel_weights
    project = load_project("city_day_clear_sky")
    shared = shared_bands(project)
    fine = box_bands_between(np.asarray(shared.edges_nm))
    wl = np.arange(360.0, 781.0, 1.0)
    patches = (spectra.macbeth_reflectances(wl) * spectra.illuminant_spd("D65", wl)[None, :]).T     # Nλ × 24
    for pattern in ("GRBG", "RCCC", "RCCB"):
        p = with_cfa(project, pattern)
        own_edges = shared_bands(p).own_edges_nm
        own = box_bands_between(np.asarray(own_edges))
        grid = np.union1d(wl, shared.edges_nm)
        direct = band_means(patches, wl, own_edges, grid)
        via_shared = band_sum_matrix(shared.edges_nm, own_edges) @ band_means(patches, wl, shared.edges_nm, grid)
        w = channel_weights(p.sensor.pixel_response, own.output_wavelengths_nm).astype(np.float64)
        a, b = direct.T @ w, via_shared.T @ w
        assert np.max(np.abs(b / a - 1.0)) < 1e-6, pattern
        assert fine.output_wavelengths_nm.size == 32


def band_means(values, wl, edges, grid):
    """Band means over the bands of `edges` of the piecewise-linear spectra `values` (Nλ × K on
    `wl`): exact integrals on `grid` (every knot of wl and every edge)."""
    from scipy.integrate import cumulative_trapezoid
    v = np.stack([np.interp(grid, wl, column) for column in values.T], axis=1)
    at = cumulative_trapezoid(v, grid, axis=0, initial=0.0)[np.searchsorted(grid, edges)]
    return np.diff(at, axis=0) / np.diff(edges)[:, None]


def test_a_cfa_edit_sequence_renders_the_city_once():
    """Bayer → RCCC → RCCB → Bayer on the window's pipeline and renderer: one render (the first);
    each pattern's scene is on its own bands; every stage after the scene reruns where the bands
    moved, and Bayer comes back from the cache."""
    session = CitySceneSession()
    calls = []

    def counted(*args, **kwargs):
        calls.append(kwargs.get("film_edges_nm"))
        return (yield from session.job(*args, **kwargs))

    renderer = SharedBandRenderer(counted)
    project = tiny_city()
    pipe = Pipeline(project)
    scenes = {}
    for cfa in ("GRBG", "RCCC", "RCCB", "GRBG"):
        project = with_cfa(project, cfa)
        pipe.set_project(project)
        pipe.city_renderer = lambda inputs, seeds, cancel, p=project: renderer.job(inputs, seeds, cancel, project=p)
        result = pipe.run()
        scenes[cfa] = result.scene
        own = box_bands(*sorted({city_scene_inputs(project).render.wavelength_min_nm,
                                 city_scene_inputs(project).render.wavelength_max_nm}), project.render.band_count)
        assert np.array_equal(result.scene.wavelengths_nm, own.output_wavelengths_nm)
        assert result.scene.meta["channel_centroids_nm"] == own.centroids_nm.tolist()
    assert len(calls) == 1 and renderer.renders == 1 and calls[0] == shared_bands(tiny_city()).edges_nm
    assert scenes["GRBG"].wavelengths_nm[0] > scenes["RCCC"].wavelengths_nm[0]
    assert rendered_inputs(with_cfa(project, "RCCC")) == rendered_inputs(project)


def test_a_patterns_bands_from_the_shared_render_match_its_own_render():
    """Same expectation: the RCCC frame from the shared render and from RCCC's own film agree in
    every band's frame mean within their Monte-Carlo noise (different samples, not bit-equal)."""
    project = tiny_city(spp=64, cfa="RCCC")
    seeds = frame_seeds(project.seed, 0)
    shared = shared_bands(project)
    session = CitySceneSession()
    fine = run_job(session.job(shared.inputs, seeds, film_edges_nm=shared.edges_nm))
    mine = own_bands(fine, shared)
    direct = run_job(session.job(city_scene_inputs(project), seeds))
    assert np.array_equal(mine.scene.wavelengths_nm, direct.scene.wavelengths_nm)
    a = mine.scene.radiance_photons.mean(axis=(0, 1))
    b = direct.scene.radiance_photons.mean(axis=(0, 1))
    assert np.max(np.abs(a / b - 1.0)) < 0.05
    assert abs(a.sum() / b.sum() - 1.0) < 0.01
    assert np.array_equal(mine.labels.depth_m, direct.labels.depth_m)


@pytest.mark.parametrize("change", [{"representation": "sensor"}, {"wavelength_min_nm": 400.0,
                                                                   "wavelength_max_nm": 700.0}])
def test_a_film_that_does_not_follow_the_cfa_is_rendered_as_it_is(change):
    project = tiny_city()
    project = project.updated(render=project.render.updated(**change))
    assert shared_bands(project) is None
    assert rendered_inputs(project) == (city_scene_inputs(project), None)

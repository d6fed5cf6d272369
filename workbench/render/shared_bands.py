"""One city render that serves every CFA pattern the sensor editor offers (the window's renders).

A 'bands' film that follows the sensor covers where its channels respond
(city_frame.sensor_film_range_nm), so a CFA edit that moves that range (with the shipped filters
Bayer 390–695 nm, RCCC/RCCB/RGBW/MONO 385–695 nm) changed the film, and the window rendered the
city again. Here the city is rendered once in box bands between the union of every pattern's band
edges (32 bands for 16 per pattern with the shipped filters): each pattern's own band is a sum of those bands, so
`own_bands` gives a pattern's render from the shared one exactly, that is the same integrals
∫ L s_k dλ as rendering the pattern's own film (only the Monte-Carlo samples differ, not the
expectation or the noise). Data sets keep their own film (city_frame.city_scene_inputs and
CitySceneSession.job without film_edges_nm): their frames and fingerprints are unchanged.
"""
from __future__ import annotations

import dataclasses
from collections import OrderedDict
from dataclasses import dataclass
from functools import lru_cache
from typing import Callable

import numpy as np

from workbench.errors import InvalidValueError
from workbench.jobs import Job
from workbench.render.city_frame import CityRender, CitySceneInputs, city_scene_inputs, sensor_film_range_nm
from workbench.render.film import EDGE_RAMP_NM, box_bands_between

KEEP_RENDERS = 3
"""Shared renders kept (the newest full render and quick look of the shown pose, and one more)."""


def pattern_band_edges_nm(pixels, band_count: int) -> dict[str, np.ndarray]:
    """Each CFA pattern's band edges (nm) for a 'bands' film following the sensor: `band_count`
    equal bands over the range sensor_film_range_nm gives `pixels` with that pattern, for every
    pattern of CFA_PATTERNS whose colour filters pixels.filter_file holds."""
    ranges = _pattern_ranges_nm(pixels.filter_file, pixels.photodiode_qe_file, pixels.ir_cut_file)
    return {pattern: np.linspace(lo, hi, band_count + 1) for pattern, (lo, hi) in ranges.items()}


@lru_cache(maxsize=16)
def _pattern_ranges_nm(filter_file: str | None, photodiode_qe_file: str | None,
                       ir_cut_file: str | None) -> dict[str, tuple[float, float]]:
    """sensor_film_range_nm of every pattern the filter file serves (cached by file names, as
    sensor.cfa.channel_qe is)."""
    from types import SimpleNamespace

    from workbench.sensor.cfa import cfa_layout
    from workbench.sensor.params import CFA_PATTERNS
    from workbench.spectrum_csv import read_spectrum
    have = set(read_spectrum(filter_file).names) if filter_file is not None else set()
    return {pattern: sensor_film_range_nm(SimpleNamespace(cfa_pattern=pattern, filter_file=filter_file,
                                                          photodiode_qe_file=photodiode_qe_file,
                                                          ir_cut_file=ir_cut_file))
            for pattern in CFA_PATTERNS if set(cfa_layout(pattern)[1]) - {"M"} <= have}


@lru_cache(maxsize=16)
def _union_edges_nm(filter_file: str | None, photodiode_qe_file: str | None, ir_cut_file: str | None,
                    band_count: int) -> tuple[float, ...]:
    """The union of every pattern's band edges (pattern_band_edges_nm), increasing."""
    ranges = _pattern_ranges_nm(filter_file, photodiode_qe_file, ir_cut_file)
    every = [np.linspace(lo, hi, band_count + 1) for lo, hi in ranges.values()]
    return tuple(np.unique(np.concatenate(every)).tolist())


@dataclass(frozen=True)
class SharedBands:
    """What the window renders for a project (`inputs`, with the range of the shared film, and
    the film's band edges `edges_nm`) and the project's own band edges `own_edges_nm`."""

    inputs: CitySceneInputs
    edges_nm: tuple[float, ...]
    own_edges_nm: tuple[float, ...]


def shared_bands(project) -> SharedBands | None:
    """The render that serves every CFA pattern of `project`'s sensor, or None where the film
    does not move with the CFA or cannot be shared: not a city, a film other than 'bands', a
    wavelength range given, render.shot_noise_ratio (its pilot reads the sensor), or two
    patterns' edges nearer than the bands' edge ramps (film.EDGE_RAMP_NM)."""
    render = project.render
    if (project.scene.kind != "city" or render.representation != "bands" or render.wavelength_min_nm is not None
            or render.shot_noise_ratio is not None):
        return None
    inputs = city_scene_inputs(project)
    own = np.linspace(inputs.render.wavelength_min_nm, inputs.render.wavelength_max_nm, render.band_count + 1)
    sensor = project.sensor
    edges = np.asarray(_union_edges_nm(sensor.filter_file, sensor.photodiode_qe_file, sensor.ir_cut_file,
                                       render.band_count))
    if not np.isin(own, edges).all() or np.min(np.diff(edges)) < EDGE_RAMP_NM:
        return None
    shared = dataclasses.replace(inputs, render=inputs.render.updated(
        wavelength_min_nm=float(edges[0]), wavelength_max_nm=float(edges[-1])))
    return SharedBands(shared, tuple(edges.tolist()), tuple(own.tolist()))


def band_sum_matrix(edges_nm, own_edges_nm) -> np.ndarray:
    """(K_own × K) float64: band-mean radiance in the bands between `edges_nm` → band-mean radiance
    in the bands between `own_edges_nm` (each of which must be one of edges_nm): the width-weighted
    mean of the bands each own band is made of."""
    edges, own = np.asarray(edges_nm, np.float64), np.asarray(own_edges_nm, np.float64)
    if not np.isin(own, edges).all():
        raise InvalidValueError(f"own band edges {np.round(own, 3).tolist()} are not all edges of the shared bands "
                                f"{np.round(edges, 3).tolist()}: render the project's own film (shared_bands gives None)")
    centres, widths = (edges[:-1] + edges[1:]) / 2, np.diff(edges)
    band = np.searchsorted(own, centres) - 1
    inside = (band >= 0) & (band < own.size - 1)
    m = np.zeros((own.size - 1, edges.size - 1))
    m[band[inside], np.nonzero(inside)[0]] = widths[inside] / np.diff(own)[band[inside]]
    return m


def own_bands(render: CityRender, shared: SharedBands) -> CityRender:
    """The shared render as the project's own film would give it: radiance in its own bands (and
    the film's meta of those bands), the labels and the rest as rendered."""
    own = box_bands_between(np.asarray(shared.own_edges_nm))
    m = band_sum_matrix(shared.edges_nm, shared.own_edges_nm).astype(np.float32)
    scene = render.scene
    radiance = scene.radiance_photons @ m.T
    meta = {**scene.meta, "channel_names": list(own.names), "channel_integrals_nm": own.integrals_nm.tolist(),
            "channel_centroids_nm": own.centroids_nm.tolist(),
            "shared_bands": {"rendered_edges_nm": list(shared.edges_nm)}}
    scene = dataclasses.replace(scene, radiance_photons=radiance, wavelengths_nm=own.output_wavelengths_nm, meta=meta)
    return dataclasses.replace(render, scene=scene, meta={**render.meta, "render": meta})


class SharedBandRenderer:
    """The window's city renderer: renders a project's SharedBands once through `renderer` (a
    RenderWorker.job or CitySceneSession.job), keeps the last KEEP_RENDERS, and gives each CFA
    pattern its own bands from them (own_bands), so a CFA edit renders nothing. `renders` counts
    the renders asked of `renderer`."""

    def __init__(self, renderer: Callable, keep: int = KEEP_RENDERS):
        self._renderer = renderer
        self._keep = keep
        self._renders: OrderedDict = OrderedDict()
        self.renders = 0

    def job(self, inputs: CitySceneInputs, seeds, cancel=None, quick_look: bool = False, *,
            project) -> Job[CityRender]:
        """The pipeline's city_renderer for `project` (whose render inputs are `inputs`): a
        Job[CityRender] in the project's own bands."""
        from workbench.stages.keys import digest
        shared = shared_bands(project)
        if shared is None or city_scene_inputs(project) != inputs:
            self.renders += 1
            return (yield from self._renderer(inputs, seeds, cancel, quick_look))
        key = digest(shared.inputs, shared.edges_nm, seeds, quick_look)
        render = self._renders.pop(key, None)
        if render is None:
            render = yield from self._renderer(shared.inputs, seeds, cancel, quick_look,
                                               film_edges_nm=shared.edges_nm)
            self.renders += 1
        if not render.scene.meta.get("cancelled"):      # a cancelled render is not kept
            self._renders[key] = render
            while len(self._renders) > self._keep:
                self._renders.popitem(last=False)
        return own_bands(render, shared)


def rendered_inputs(project) -> tuple:
    """What rendering `project`'s city in the window reads (its SharedBands' inputs and edges, or
    its own render inputs): equal for two projects whose window renders are the same."""
    shared = shared_bands(project)
    return (city_scene_inputs(project), None) if shared is None else (shared.inputs, shared.edges_nm)

"""The real lens behind the psf_grid and raytrace levels, and the first-order values it implies."""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from workbench.errors import InvalidValueError
from workbench.optics.params import OpticsParams


def prepare_lens(lens, focal_length_mm: float | None, f_number: float):
    """`lens` scaled to focal_length_mm (None keeps its own) with its stop resized so that its
    paraxial f-number is f_number: the lens every level images with."""
    from workbench.optics.lens.paraxial import paraxial
    if focal_length_mm is not None:
        lens = lens.scaled(focal_length_mm / paraxial(lens).efl_mm)
    native = paraxial(lens).f_number
    stop = lens.surfaces[lens.stop_index]
    return lens.with_stop_semi_aperture(stop.semi_aperture_mm * native / f_number)


@lru_cache(maxsize=16)
def _prepared_lens(lens_file: str, focal_length_mm: float | None, f_number: float):
    from workbench.optics.lens.io import load_lens
    return prepare_lens(load_lens(lens_file), focal_length_mm, f_number)


def prepared_lens(params: OpticsParams):
    """The prescription of params.lens_file, scaled (if asked) and stopped to params.f_number,
    focused at infinity. ValueError when params has no lens file."""
    if params.lens_file is None:
        raise InvalidValueError(f"optics model {params.model!r} needs a lens: set lens_file (a prescription "
                         "in the lens library, e.g. 'dgauss.50mm')")
    return _prepared_lens(params.lens_file,
                          params.focal_length_mm if params.scale_lens_to_focal_length else None,
                          params.f_number)


def effective_focal_length_m(params: OpticsParams) -> float:
    """The focal length every level images with (m): the paraxial EFL of the prepared lens when
    params.lens_file is set (equal to focal_length_mm when scale_lens_to_focal_length), else
    params.focal_length_mm."""
    if params.lens_file is None:
        return params.focal_length_m
    from workbench.optics.lens.paraxial import paraxial
    return paraxial(prepared_lens(params)).efl_mm * 1e-3


def effective_params(params: OpticsParams) -> OpticsParams:
    """params with focal_length_mm replaced by effective_focal_length_m (the lens's paraxial
    focal length when a lens is set)."""
    if params.lens_file is None or params.scale_lens_to_focal_length:
        return params
    return params.model_copy(update={"focal_length_mm": effective_focal_length_m(params) * 1e3})


FAR_FOCAL_LENGTHS = 1e4


def focused_lens(params: OpticsParams, focus_distance_m: float):
    """(prepared lens focused on an object `focus_distance_m` from the entrance pupil, that
    object's distance from the first vertex in m). Objects beyond 10⁴ focal lengths are treated
    as at infinity (indistinguishable, and ray aiming is better conditioned)."""
    from workbench.optics.lens.paraxial import focus, paraxial
    lens = prepared_lens(params)
    pdata = paraxial(lens)
    obj_m = focus_distance_m - pdata.entrance_pupil_mm * 1e-3
    if obj_m > FAR_FOCAL_LENGTHS * pdata.efl_mm * 1e-3:
        obj_m = float("inf")
    nearest_m = (pdata.ffl_mm + pdata.entrance_pupil_mm) * 1e-3     # the front focal point
    if not obj_m > 0 or not focus_distance_m > nearest_m:
        raise InvalidValueError(f"lens {lens.name!r} cannot focus {focus_distance_m:.6g} m from its entrance pupil "
                                f"(optics.focus_distance_m, else scene.distance_m): it forms a real image only "
                                f"of objects beyond its front focal point, {nearest_m:.6g} m from the entrance pupil")
    return focus(lens, obj_m), obj_m


def pinhole_image_distance_m(params: OpticsParams, focus_distance_m: float) -> float:
    """Image distance (m) of the pinhole camera at the entrance pupil that images like
    params.lens_file focused `focus_distance_m` from it: |m|·s, with m the prepared lens's
    paraxial magnification. (The thin-lens 1/(1/f − 1/s) measures s from a principal plane, which
    in a thick lens lies millimetres from the entrance pupil: negligible far away, off by orders
    of magnitude within a few focal lengths.)"""
    from workbench.optics.lens.paraxial import lateral_magnification
    lens, obj_m = focused_lens(params, focus_distance_m)
    if math.isinf(obj_m):
        return effective_focal_length_m(params)
    return abs(lateral_magnification(lens, obj_m)) * focus_distance_m


RADIOMETRY_HEIGHTS = 24
RADIOMETRY_SIDE = 96


def irradiance_table(lens, max_height_mm: float, wavelength_nm: float) -> tuple[np.ndarray, np.ndarray]:
    """(image heights mm, E/L in sr): PBRT's camera-equation integral ∫cos⁴θ/z² dA over the
    traced exit pupil, 96² rays per height, at 24 heights from the axis to max_height_mm."""
    from workbench.optics.lens.analysis import irradiance_per_radiance
    heights = np.linspace(0.0, max_height_mm, RADIOMETRY_HEIGHTS)
    return heights, np.array([irradiance_per_radiance(lens, float(h), float(wavelength_nm),
                                                      n_side=RADIOMETRY_SIDE) for h in heights])

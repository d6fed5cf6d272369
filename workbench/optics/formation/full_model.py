"""The full optics model's camera and optical image: a real lens traced for every camera ray by the
renderer (workbench.render.lens_camera), whose film already holds sensor irradiance.

`full_model_camera` prepares the project's lens as the other levels prepare it (lens_setup) and
derives the sensor geometry; `full_model_optical_image` turns the film into an OpticalImage
(transmittance, optional diffraction). Neither needs Mitsuba.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.errors import InvalidValueError, check_finite
from workbench.optics.formation import diffraction, fourier, geometry, lens_setup
from workbench.optics.lens.model import Lens
from workbench.optics.lens.paraxial import paraxial
from workbench.optics.types import OpticalImage


@dataclass(frozen=True)
class FullModelCamera:
    """The lens the full model renders through and the sensor geometry it implies.

    lens: the project's prescription scaled and stopped as formation/ does (lens_setup), focused on
        `focus_distance_m` (from the entrance pupil). image_distance_m: thin-lens image distance of
        that focus (formation/'s convention: it sets the field of view and the working f-number).
    """

    lens: Lens
    sensor_width_mm: float
    image_distance_m: float
    focal_length_m: float
    f_number: float
    focus_distance_m: float

    @property
    def fov_deg(self) -> float:
        """Horizontal field of view (deg) of the sensor width at the image distance (paraxial)."""
        return math.degrees(2.0 * math.atan(self.sensor_width_mm * 1e-3 / 2.0 / self.image_distance_m))

    @property
    def working_f_number(self) -> float:
        return self.f_number * self.image_distance_m / self.focal_length_m


def full_model_camera(params, camera: geometry.CameraGeometry) -> FullModelCamera:
    """The full model's camera for OpticsParams `params` (lens_file required) on the camera
    geometry `camera` (the project's: stages.geometry.project_geometry): the lens prepared as
    formation/ prepares it (scale_lens_to_focal_length, stop resized to f_number), focused on
    camera.focus_distance_m; the sensor is camera.sensor_width_m wide at camera.image_distance_m."""
    lens, _ = lens_setup.focused_lens(params, camera.focus_distance_m)
    return FullModelCamera(lens, float(camera.sensor_width_m * 1e3), float(camera.image_distance_m),
                           float(camera.focal_length_m), float(paraxial(lens).f_number),
                           float(camera.focus_distance_m))


def full_model_optical_image(irradiance_photons: np.ndarray, wavelengths_nm: np.ndarray,
                             camera: FullModelCamera, params, *, depth_m=None, meta: dict | None = None):
    """The OpticalImage of a render through workbench.render.lens_camera.lens_sensor_dict(camera.lens, …, weight='irradiance'):
    the film already holds sensor irradiance (photons/s/m²/nm, upright, on square samples of
    sensor_width_mm / columns); this applies the transmittance and, with
    params.raytrace_diffraction, the Airy pattern of the working f-number integrated over each
    sample (as the raytrace level does: geometric blur ⊛ Airy)."""
    irr = np.asarray(irradiance_photons, dtype=np.float64) * params.transmittance
    if irr.ndim != 3 or irr.shape[2] != np.size(wavelengths_nm):
        raise InvalidValueError(f"irradiance_photons must be H×W×Nλ with Nλ = {np.size(wavelengths_nm)}, got {irr.shape}")
    dx = camera.sensor_width_mm * 1e-3 / irr.shape[1]
    clipped = 0.0
    if params.raytrace_diffraction:
        diffraction.check_airy_kernel(float(np.max(wavelengths_nm)) * 1e-9, camera.working_f_number, dx)
        for b, wl in enumerate(np.asarray(wavelengths_nm, dtype=np.float64)):
            kernel = diffraction.airy_cell_kernel(wl * 1e-9, camera.working_f_number, dx)
            irr[..., b:b + 1], frac = fourier.apply_otf(irr[..., b:b + 1], dx, lambda c, fy, fx: 1.0,
                                                       fourier.pad_width(irr.shape[:2], kernel.shape[0]), kernel)
            clipped = max(clipped, frac)
    info = {"model": "full (Mitsuba lens camera)", "lens": camera.lens.name,
            "image_distance_m": camera.image_distance_m, "focus_distance_m": camera.focus_distance_m,
            "working_f_number": camera.working_f_number, "diffraction": params.raytrace_diffraction,
            "clipped_fraction": clipped, **(meta or {})}
    return OpticalImage(check_finite("optics full model", irr).astype(np.float32),
                        np.asarray(wavelengths_nm, dtype=np.float64).copy(), dx, camera.focal_length_m,
                        camera.f_number, depth_m=depth_m, meta=info)

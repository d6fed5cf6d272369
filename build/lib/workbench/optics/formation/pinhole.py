"""Level 0: pinhole projection with the camera equation, cos⁴ fall-off and radial distortion."""
from __future__ import annotations

import math

import numpy as np

from workbench.optics.formation import geometry
from workbench.optics.params import OpticsParams
from workbench.optics.types import OpticalImage, register_optics
from workbench.scene.types import Scene


def check_finite(stage: str, irradiance: np.ndarray) -> np.ndarray:
    """Raise if a stage produced NaN/Inf; return the array as float32."""
    if not np.all(np.isfinite(irradiance)):
        raise FloatingPointError(f"optics '{stage}': irradiance has NaN/Inf (check the scene "
                                 "radiance range and the optics parameters)")
    return irradiance.astype(np.float32, copy=False)


def radiance_to_irradiance(scene: Scene, params: OpticsParams) -> OpticalImage:
    """Sensor-plane irradiance (photons/s/m²/nm) of a pinhole camera, image upright.

    E = π T L / (1 + 4 N² (1 + |m|)²) × off-axis fall-off, m from the thin-lens law at the
    focus distance (default the scene distance); samples spaced 2·d_image·tan(fov/2)/W."""
    f_m = params.focal_length_m
    s_m = geometry.focus_object_distance_m(scene, params)
    d_img = geometry.image_distance_m(f_m, s_m)
    m = geometry.magnification(f_m, s_m)
    rows, cols = scene.shape
    dx = geometry.sample_spacing_m(scene.fov_deg, cols, d_img)
    gain = geometry.camera_equation_factor(params.f_number, m, params.transmittance)
    irr = scene.radiance_photons.astype(np.float64) * gain
    if params.off_axis == "cos4th":
        x, y = geometry.sample_positions_m((rows, cols), dx)
        fall = geometry.cos4th_falloff(np.hypot(x, y), d_img, params.f_number, m,
                                       dx * math.hypot(rows, cols))
        irr *= fall[..., None]
    irr = geometry.distort_image(irr, dx, d_img, params.distortion_k)
    return OpticalImage(check_finite("pinhole", irr), scene.wavelengths_nm.copy(), dx, d_img,
                        params.f_number, depth_m=scene.depth_m,
                        meta={"model": "pinhole", "image_distance_m": d_img, "magnification": m,
                              "focal_length_m": f_m})


register_optics("pinhole")(radiance_to_irradiance)

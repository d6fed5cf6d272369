"""Level 0: pinhole projection with the camera equation, cos⁴ fall-off and radial distortion."""
from __future__ import annotations

import math

import numpy as np

from workbench.errors import check_finite
from workbench.optics.formation import geometry
from workbench.optics.params import OpticsParams
from workbench.optics.types import OpticalImage, register_optics
from workbench.scene.types import Scene


def radiance_to_irradiance(scene: Scene, params: OpticsParams,
                           camera: geometry.CameraGeometry | None = None) -> OpticalImage:
    """Sensor-plane irradiance (photons/s/m²/nm) of a pinhole camera, image upright.

    E = π T L / (1 + 4 N² (1 + |m|)²) × off-axis fall-off, m from the thin-lens law at the
    focus distance; focal length, image distance and sample spacing from `camera`
    (geometry.scene_geometry: the scene's own field of view when None)."""
    g = geometry.scene_geometry(scene, params, camera)
    f_m, d_img, m = g.focal_length_m, g.image_distance_m, g.magnification
    rows, cols = scene.shape
    dx = g.sample_spacing_m
    gain = geometry.camera_equation_factor(params.f_number, m, params.transmittance)
    if params.off_axis == "cos4th":           # one float32 product per sample: gain × fall-off (float64) × L
        x, y = geometry.sample_positions_m((rows, cols), dx)
        fall = geometry.cos4th_falloff(np.hypot(x, y), d_img, params.f_number, m,
                                       dx * math.hypot(rows, cols))
        irr = np.multiply(scene.radiance_photons, (gain * fall)[..., None].astype(np.float32), dtype=np.float32)
    else:
        irr = np.multiply(scene.radiance_photons, np.float32(gain), dtype=np.float32)
    irr = geometry.distort_image(irr, dx, d_img, params.distortion_k).astype(np.float32, copy=False)
    return OpticalImage(check_finite("optics pinhole", irr), scene.wavelengths_nm.copy(), dx, d_img,
                        params.f_number, depth_m=scene.depth_m,
                        meta={"model": "pinhole", "image_distance_m": d_img, "magnification": m,
                              "focal_length_m": f_m})


register_optics("pinhole")(radiance_to_irradiance)

"""Level 2: diffraction-limited, shift-invariant OTF per wavelength (circular aperture)."""
from __future__ import annotations

import math

import numpy as np

from workbench.errors import check_finite
from workbench.optics.formation import fourier, geometry, pinhole
from workbench.optics.params import OpticsParams
from workbench.optics.types import OpticalImage, register_optics
from workbench.scene.types import Scene


def diffraction_mtf(frequency_cyc_per_m: np.ndarray, wavelength_m: float, working_f_number: float) -> np.ndarray:
    """Incoherent diffraction-limited OTF of a circular pupil (real, ≥ 0).

    s = ν/νc with cut-off νc = 1/(λ N_w); OTF = (2/π)(acos s − s√(1 − s²)) for s < 1, else 0."""
    s = np.minimum(np.abs(frequency_cyc_per_m) * wavelength_m * working_f_number, 1.0)
    return (2.0 / np.pi) * (np.arccos(s) - s * np.sqrt(1.0 - s * s))


def check_airy_kernel(wavelength_m: float, working_f_number_: float, spacing_m: float,
                      radius_airy: float = 40.0) -> tuple[int, int]:
    """(half-width in samples, sub-samples per cell) of airy_cell_kernel's kernel; raises its
    InvalidValueError without building anything, so a model can refuse before its slow part
    (the longest wavelength's kernel is the largest)."""
    lam_n = wavelength_m * working_f_number_
    supersample = int(np.clip(math.ceil(4.0 * spacing_m / lam_n), 4, 64))
    half = int(math.ceil(max(radius_airy * lam_n / spacing_m, 1.0)))
    fine_samples = ((2 * half + 1) * supersample) ** 2
    if fine_samples > fourier.MAX_BLUR_PLANE_SAMPLES:
        raise fourier.blur_too_wide(half, "its cell-integrated Airy kernel too large to build",
                                    fine_samples * 8 / 2 ** 30)
    return half, supersample


def airy_cell_kernel(wavelength_m: float, working_f_number_: float, spacing_m: float,
                     radius_airy: float = 40.0) -> np.ndarray:
    """The Airy pattern integrated over each sample cell (odd-sized, sums to 1): the energy a
    point at a cell centre sends into every cell. Out to `radius_airy` × λN (≥ 1 cell); the
    ~0.5 % of light in the rings beyond is redistributed by the normalisation. Each cell is
    integrated on a sub-grid of ≤ λN/4 (at most 64² points). InvalidValueError (fourier.blur_too_wide)
    where that grid would exceed fourier.MAX_BLUR_PLANE_SAMPLES."""
    from scipy.special import j1
    lam_n = wavelength_m * working_f_number_
    half, supersample = check_airy_kernel(wavelength_m, working_f_number_, spacing_m, radius_airy)
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    axis = ((np.arange(-half, half + 1)[:, None] + sub[None, :]).ravel()) * spacing_m
    yy, xx = np.meshgrid(axis, axis, indexing="ij")
    x = np.pi * np.hypot(xx, yy) / lam_n
    safe = np.where(x == 0, 1.0, x)
    fine = np.where(x == 0, 1.0, (2.0 * j1(safe) / safe) ** 2)
    n = 2 * half + 1
    k = fine.reshape(n, supersample, n, supersample).sum(axis=(1, 3))
    return k / k.sum()


def working_f_number(optical_image: OpticalImage, focal_length_m: float) -> float:
    """N_w = N · d_image / f: the f-number that sets the cut-off on a focused image plane."""
    return optical_image.f_number * optical_image.meta["image_distance_m"] / focal_length_m


def blur_radius_samples(wavelengths_nm: np.ndarray, n_w: float, spacing_m: float) -> float:
    """Radius (samples) that holds all but ~0.5 % of the longest wavelength's Airy pattern."""
    return 40.0 * float(np.max(wavelengths_nm)) * 1e-9 * n_w / spacing_m


def radiance_to_irradiance(scene: Scene, params: OpticsParams,
                           camera: geometry.CameraGeometry | None = None) -> OpticalImage:
    """Pinhole irradiance (camera equation, fall-off, distortion) blurred by the diffraction OTF.

    Padding mirrors the image (see fourier.py). Ringing below zero (from cutting the OTF at
    the sampling grid) is clipped to 0; meta['clipped_fraction'] says how many samples."""
    g = geometry.scene_geometry(scene, params, camera)
    oi = pinhole.radiance_to_irradiance(scene, params, g)
    n_w = working_f_number(oi, g.focal_length_m)
    wl_m = oi.wavelengths_nm * 1e-9
    pad = fourier.pad_width(oi.shape, blur_radius_samples(oi.wavelengths_nm, n_w, oi.sample_spacing_m))

    def otf(c, fy, fx):
        return diffraction_mtf(np.hypot(fy, fx), wl_m[c], n_w)

    irr, clipped = fourier.apply_otf(oi.irradiance_photons, oi.sample_spacing_m, otf, pad)
    return OpticalImage(check_finite("optics diffraction_limited", irr).astype(np.float32), oi.wavelengths_nm,
                        oi.sample_spacing_m, g.focal_length_m, params.f_number, depth_m=oi.depth_m,
                        meta={**oi.meta, "model": "diffraction_limited", "working_f_number": n_w,
                              "pad_samples": pad, "padding": "symmetric", "clipped_fraction": clipped})


register_optics("diffraction_limited")(radiance_to_irradiance)

"""Level 1: thin lens with depth-dependent defocus, applied by depth layers, plus diffraction.

Circle of confusion on the sensor (focused at s, object at axial distance z, aperture A = f/N):
c = A · f · |z − s| / (z (s − f)) = K·|1/s − 1/z| with K = A f s/(s − f). The layers are
spaced evenly in c from the smallest to the largest blur in the frame, and every sample's
light is split linearly between the two layers that bracket its own c. Each layer's light is
blurred by the defocus (a disk of diameter c, or a Gaussian of the same second moment, σ = c/4)
and the diffraction OTF. Blurs up to 2.44 samples use the analytic OTF 2J₁(πcρ)/(πcρ), which
stays positive up to Nyquist and resolves sub-sample defocus; larger blurs use the disk's area
coverage sampled on the grid (non-negative, so its ringing cannot add light). The layers are
summed: light is conserved, occlusion at depth edges is not modelled (a blurred
background does not hide behind a sharp foreground).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import j1

from workbench.errors import InvalidValueError, check_finite
from workbench.optics.formation import diffraction, fourier, geometry, pinhole
from workbench.optics.params import OpticsParams
from workbench.optics.types import OpticalImage, register_optics
from workbench.scene.types import Scene

SMALL_BLUR_SAMPLES = 2.44   # below this CoC (samples) the pillbox OTF has no zero before Nyquist
FLAT_BLUR_SAMPLES = 0.05    # a spread of blur diameters below this (samples) is one depth layer


MAX_BLUR_IMAGE_WIDTHS = 4          # a wider defocus blur is refused (the padded FFT grid grows with it)


def depth_varies(coc_spread_m: float, spacing_m: float) -> bool:
    """Whether blur circles spread over more than FLAT_BLUR_SAMPLES samples, so that a scene
    needs more than one depth layer (shared by every level that splits a scene by depth)."""
    return coc_spread_m > FLAT_BLUR_SAMPLES * spacing_m


def circle_of_confusion_m(depth_z_m: np.ndarray, focal_length_m: float, f_number: float,
                          focus_distance_m: float) -> np.ndarray:
    """Blur-circle diameter (m) on the sensor for objects at axial distance z (inf allowed)."""
    z = np.asarray(depth_z_m, dtype=np.float64)
    if np.any(z <= focal_length_m):
        raise InvalidValueError(f"thin lens: object depths must exceed the focal length {focal_length_m} m; "
                         f"the nearest is {float(z.min())} m")
    inv_s = 0.0 if math.isinf(focus_distance_m) else 1.0 / focus_distance_m
    return coc_scale_m(focal_length_m, f_number, focus_distance_m) * np.abs(inv_s - 1.0 / z)


def coc_scale_m(focal_length_m: float, f_number: float, focus_distance_m: float) -> float:
    """K = A f s/(s − f) (m²): CoC diameter per unit of |1/s − 1/z| (1/m)."""
    inv_s = 0.0 if math.isinf(focus_distance_m) else 1.0 / focus_distance_m
    if focal_length_m * inv_s >= 1.0:
        raise InvalidValueError(f"thin lens: focus distance {focus_distance_m} m must exceed the focal "
                         f"length {focal_length_m} m")
    return (focal_length_m / f_number) * focal_length_m / (1.0 - focal_length_m * inv_s)


def defocus_otf(freq_cyc_per_m: np.ndarray, diameter_m: float, shape: str = "pillbox") -> np.ndarray:
    """Analytic defocus OTF: pillbox 2J₁(πcρ)/(πcρ), or Gaussian exp(−2π²σ²ρ²) with σ = c/4."""
    rho = np.asarray(freq_cyc_per_m, dtype=np.float64)
    if diameter_m == 0:
        return np.ones_like(rho)
    if shape == "gaussian":
        return np.exp(-2.0 * np.pi ** 2 * (diameter_m / 4.0) ** 2 * rho ** 2)
    x = np.pi * diameter_m * rho
    safe = np.where(x == 0, 1.0, x)
    return np.where(x == 0, 1.0, 2.0 * j1(safe) / safe)


def defocus_kernel(diameter_samples: float, shape: str = "pillbox", supersample: int = 5) -> np.ndarray:
    """Normalised, non-negative blur kernel on the sample grid (odd size, centred).

    'pillbox': area coverage of a disk of the given diameter; 'gaussian': σ = diameter/4 (the
    same second moment). Each sample averages supersample² points, so blurs below one sample
    reduce to (nearly) a delta and the kernel never rings."""
    radius = 0.5 * diameter_samples
    sigma = max(diameter_samples / 4.0, 1e-3)
    half = math.ceil(radius if shape == "pillbox" else 4.0 * sigma) + 1
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    axis = (np.arange(-half, half + 1)[:, None] + sub[None, :]).ravel()
    yy, xx = np.meshgrid(axis, axis, indexing="ij")
    r2 = xx * xx + yy * yy
    if shape == "pillbox":
        fine = (r2 <= radius * radius).astype(np.float64)
        if not fine.any():
            fine[r2 == r2.min()] = 1.0
    else:
        fine = np.exp(-0.5 * r2 / sigma ** 2)
    n = 2 * half + 1
    k = fine.reshape(n, supersample, n, supersample).sum(axis=(1, 3))
    return k / k.sum()


def layer_weights(coc_map_m: np.ndarray, layer_coc_m: np.ndarray) -> np.ndarray:
    """L×H×W weights (summing to 1 per sample) splitting each sample linearly between the two
    layers whose blur diameters bracket its own."""
    n = layer_coc_m.size
    if n == 1:
        return np.ones((1,) + coc_map_m.shape)
    pos = np.interp(coc_map_m, layer_coc_m, np.arange(n, dtype=np.float64))
    below = np.minimum(np.floor(pos).astype(int), n - 2)
    frac = pos - below
    w = np.zeros((n,) + coc_map_m.shape)
    np.put_along_axis(w, below[None], (1.0 - frac)[None], axis=0)
    np.put_along_axis(w, below[None] + 1, frac[None], axis=0)
    return w


def axial_depth_m(scene: Scene, spacing_m: float, image_distance: float) -> np.ndarray:
    """Axial object distance z per sample: depth along the ray × cos(field angle); the scene
    distance everywhere when the scene has no depth map."""
    if scene.depth_m is None:
        return np.full(scene.shape, scene.distance_m)
    x, y = geometry.sample_positions_m(scene.shape, spacing_m)
    return np.asarray(scene.depth_m, dtype=np.float64) * image_distance / np.sqrt(image_distance ** 2 + x * x + y * y)


def radiance_to_irradiance(scene: Scene, params: OpticsParams,
                           camera: geometry.CameraGeometry | None = None) -> OpticalImage:
    """Pinhole irradiance, then per depth layer defocus × diffraction OTF filtering."""
    g = geometry.scene_geometry(scene, params, camera)
    oi = pinhole.radiance_to_irradiance(scene, params, g)
    f_m, d_img, s_m = g.focal_length_m, g.image_distance_m, g.focus_distance_m
    z = axial_depth_m(scene, oi.sample_spacing_m, d_img)
    if np.any(z <= f_m):
        raise InvalidValueError(f"thin lens: scene depths must exceed the focal length {f_m} m; "
                         f"the nearest is {float(z.min())} m")
    inv_s = 0.0 if math.isinf(s_m) else 1.0 / s_m
    k_m = coc_scale_m(f_m, params.f_number, s_m)
    coc_map = k_m * np.abs(inv_s - 1.0 / z)
    lo, hi = float(coc_map.min()), float(coc_map.max())
    n_layers = params.depth_layers if depth_varies(hi - lo, oi.sample_spacing_m) and params.depth_layers > 1 else 1
    coc = np.linspace(lo, hi, n_layers) if n_layers > 1 else np.array([0.5 * (lo + hi)])
    weights = layer_weights(coc_map, coc)
    blur_samples = 2.0 * float(coc.max()) / oi.sample_spacing_m
    if blur_samples > MAX_BLUR_IMAGE_WIDTHS * max(oi.shape):
        from workbench.errors import ParameterError
        raise ParameterError("optics.focus_distance_m", s_m,
                             f"a focus farther from the focal length {f_m:.4g} m: the defocus blur of the scene "
                             f"would be {blur_samples:,.0f} samples wide, over {MAX_BLUR_IMAGE_WIDTHS} image widths "
                             f"({MAX_BLUR_IMAGE_WIDTHS * max(oi.shape):,} samples; e.g. focus at the scene, "
                             f"{float(np.median(z)):.3g} m)")
    n_w = diffraction.working_f_number(oi, f_m)
    wl_m = oi.wavelengths_nm * 1e-9
    pad = fourier.pad_width(oi.shape, max(diffraction.blur_radius_samples(oi.wavelengths_nm, n_w,
                                                                          oi.sample_spacing_m),
                                          2.0 * float(coc.max()) / oi.sample_spacing_m))
    total = np.zeros(oi.irradiance_photons.shape, dtype=np.float64)
    clipped = 0.0
    for i in range(n_layers):
        if not weights[i].any():
            continue
        part = oi.irradiance_photons * weights[i][..., None]

        coc_samples = coc[i] / oi.sample_spacing_m
        analytic = coc_samples <= SMALL_BLUR_SAMPLES

        def otf(c, fy, fx, d=coc[i] if analytic else 0.0):
            rho = np.hypot(fy, fx)
            return defocus_otf(rho, d, params.defocus_kernel) * diffraction.diffraction_mtf(rho, wl_m[c], n_w)

        kernel = None if analytic else defocus_kernel(coc_samples, params.defocus_kernel)
        blurred, frac = fourier.apply_otf(part, oi.sample_spacing_m, otf, pad, kernel)
        total += blurred
        clipped = max(clipped, frac)
    return OpticalImage(check_finite("optics thin_lens", total).astype(np.float32), oi.wavelengths_nm, oi.sample_spacing_m,
                        f_m, params.f_number, depth_m=oi.depth_m,
                        meta={**oi.meta, "model": "thin_lens", "focus_distance_m": s_m,
                              "layers": n_layers, "coc_m": coc.tolist(), "working_f_number": n_w,
                              "defocus_kernel": params.defocus_kernel, "clipped_fraction": clipped})


register_optics("thin_lens")(radiance_to_irradiance)

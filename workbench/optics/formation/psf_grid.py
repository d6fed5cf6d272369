"""Level 3: field × wavelength PSF grid of a real lens, with its distortion and illumination.

Steps, all from the lens engineer's traced quantities (workbench.optics.lens):
1. the scene is projected as by the pinhole (same sampling, image upright);
2. distortion and lateral colour: each band is resampled so that the field angle θ lands at
   the chief ray's real height (traced at `psf_wavelengths` nodes, interpolated between);
3. radiometry: irradiance per radiance (PBRT's ∫cos⁴θ/z² over the traced exit pupil) against
   image height, so cos⁴, vignetting and pupil aberration come from the lens, × transmittance;
4. blur: diffraction PSFs (traced aberrations included) at `psf_field_zones` heights from the
   centre to the corner and at the wavelength nodes. The light of each sample is split between
   the zones that bracket its radius and the `psf_azimuths` orientations that bracket its
   azimuth (linear weights), each share is convolved with its zone's PSF turned to point
   outwards, and the bands mix the two nearest wavelength nodes. Sums of shares are exact, so
   light is conserved; between zones the PSF is a blend, not a traced one. The lens PSFs are
   pixel-integrated (energy per output cell), which is exact for a scene of uniform patches
   sampled at cell centres; the diffraction level instead filters by the OTF on the sample
   grid (ISETCam), so the two differ slightly when the PSF is smaller than a sample.
The object distance is the focus distance (a flat scene; depth is ignored at this level).
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy import fft, ndimage

from workbench.optics.formation import fourier, geometry, lens_setup, pinhole
from workbench.optics.params import OpticsParams
from workbench.optics.types import OpticalImage, register_optics
from workbench.scene.types import Scene


def hat_weights(values: np.ndarray, nodes: np.ndarray, periodic: bool = False) -> np.ndarray:
    """K×… linear-interpolation weights of `values` on sorted `nodes` (sum 1 everywhere).
    periodic: nodes are angles evenly spaced over 2π."""
    k = nodes.size
    if k == 1:
        return np.ones((1,) + values.shape)
    if periodic:
        pos = np.mod(values / (2 * np.pi) * k, k)
        lo = np.floor(pos).astype(int) % k
        hi = (lo + 1) % k
    else:
        pos = np.interp(values, nodes, np.arange(k, dtype=np.float64))
        lo = np.minimum(np.floor(pos).astype(int), k - 2)
        hi = lo + 1
    frac = pos - np.floor(pos) if periodic else pos - lo
    w = np.zeros((k,) + values.shape)
    np.put_along_axis(w, lo[None], (1.0 - frac)[None], axis=0)
    hi_w = np.take_along_axis(w, hi[None], axis=0) + frac[None]
    np.put_along_axis(w, hi[None], hi_w, axis=0)
    return w


def _wavelength_nodes(wavelengths_nm: np.ndarray, count: int) -> np.ndarray:
    if count == 1 or wavelengths_nm.size == 1:
        return np.array([float(np.median(wavelengths_nm))])
    return np.linspace(wavelengths_nm.min(), wavelengths_nm.max(), min(count, wavelengths_nm.size))


def _psf_size(lens, f_number: float, wl_max_nm: float, max_field_deg: float, spacing_um: float,
              object_distance_m: float) -> int:
    """Odd PSF grid size covering 3× the largest RMS spot and the Airy pattern's first rings."""
    from workbench.optics.lens import spot_diagram
    rms = 0.0
    for angle in np.linspace(0.0, max_field_deg, 4):
        try:
            rms = max(rms, spot_diagram(lens, float(angle), wl_max_nm, object_distance_m, n_side=16).rms_um)
        except ValueError:
            pass
    radius_um = 3.0 * rms + 5.0 * wl_max_nm * 1e-3 * f_number
    return int(np.clip(2 * math.ceil(radius_um / spacing_um) + 1, 7, 129))


def _oriented(psf: np.ndarray, azimuth_rad: float) -> np.ndarray:
    """The lens PSF (rows along +y = outward, in sensor axes) as a kernel in image-array
    coordinates for an output sample whose outward direction is `azimuth_rad` clockwise from up."""
    k = psf[::-1, :]                       # array rows run downwards: +y outward becomes 'up'
    if azimuth_rad:
        k = ndimage.rotate(k, -math.degrees(azimuth_rad), reshape=False, order=1, mode="constant")
    k = np.clip(k, 0.0, None)
    return k / k.sum()


@lru_cache(maxsize=8)
def lens_tables(lens, object_distance_m: float, image_distance: float, r_max_m: float,
                nodes_nm: tuple[float, ...], n_zones: int, spacing_m: float) -> dict:
    """Traced data of a focused lens, cached (the expensive part of this level):
    'ru'/'rd' (per node): pinhole height → real chief-ray height (m); 'heights', 'e': irradiance
    per radiance against height (per node); 'zones' (m), 'psfs' (zones × nodes × size²)."""
    from workbench.optics.lens import chief_ray_on_sensor, paraxial, psf_diffraction
    ru_table = np.linspace(0.0, max(r_max_m * 1.3, 0.02 * image_distance), 25)
    ru, rd, e = [], [], []
    for wl_n in nodes_nm:
        hs = []
        for r_u in ru_table:
            try:
                hs.append(chief_ray_on_sensor(lens, math.degrees(math.atan(r_u / image_distance)), wl_n,
                                              object_distance_m)[1] * 1e-3)
            except ValueError:
                break
        if len(hs) < 2 or np.any(np.diff(hs) <= 0):
            raise ValueError(f"psf_grid: lens {lens.name!r} does not image the field monotonically "
                             f"at {wl_n:.0f} nm (chief rays traced to {len(hs)} heights)")
        ru.append(ru_table[:len(hs)])
        rd.append(np.array(hs))
        heights_mm, e_n = lens_setup.irradiance_table(lens, r_max_m * 1e3, wl_n)
        e.append(e_n)
    zones = np.linspace(0.0, r_max_m, n_zones)
    max_field = math.degrees(math.atan(r_max_m / image_distance))
    size = _psf_size(lens, paraxial(lens).f_number, max(nodes_nm), max_field, spacing_m * 1e6, object_distance_m)
    psfs = np.zeros((zones.size, len(nodes_nm), size, size))
    for z_i, h in enumerate(zones):
        for n_i, wl_n in enumerate(nodes_nm):
            try:
                psfs[z_i, n_i] = psf_diffraction(lens, float(h) * 1e3, wl_n, object_distance_m, spacing_m * 1e6, size)
            except ValueError:
                psfs[z_i, n_i] = psfs[z_i - 1, n_i] if z_i else 0.0   # vignetted: reuse the inner zone
    return {"ru": ru, "rd": rd, "heights": heights_mm * 1e-3, "e": np.array(e), "zones": zones, "psfs": psfs,
            "size": size}


def radiance_to_irradiance(scene: Scene, params: OpticsParams) -> OpticalImage:
    """Irradiance through params.lens_file by a field/wavelength PSF grid (see module doc)."""
    from workbench.optics.lens import paraxial
    params = lens_setup.effective_params(params)
    s_m = geometry.focus_object_distance_m(scene, params)
    lens, obj_m = lens_setup.focused_lens(params, s_m)
    pdata = paraxial(lens)
    d_img = geometry.image_distance_m(pdata.efl_mm * 1e-3, s_m)
    radiance = scene.radiance_photons.astype(np.float64)           # on the pinhole's grid
    rows, cols, n_bands = radiance.shape
    dx = geometry.sample_spacing_m(scene.fov_deg, cols, d_img)
    x, y = geometry.sample_positions_m((rows, cols), dx)
    r_out = np.hypot(x, y)
    r_max = float(r_out.max()) * 1.0001
    wl = scene.wavelengths_nm
    nodes = _wavelength_nodes(wl, params.psf_wavelengths)
    band_w = hat_weights(wl, nodes)                              # nodes × bands
    tab = lens_tables(lens, obj_m, d_img, r_max, tuple(float(v) for v in nodes), params.psf_field_zones, dx)

    # distortion / lateral colour and radiometry, per band from the wavelength nodes
    ru_at_out = np.stack([np.where(r_out <= rd[-1], np.interp(r_out, rd, ru), np.inf)
                          for ru, rd in zip(tab["ru"], tab["rd"])])
    gain = np.stack([np.interp(r_out, tab["heights"], e) for e in tab["e"]])
    for b in range(n_bands):
        ru = np.tensordot(band_w[:, b], np.where(np.isfinite(ru_at_out), ru_at_out, 0.0), axes=1)
        outside = np.tensordot(band_w[:, b], ~np.isfinite(ru_at_out), axes=1) > 0
        scale = np.divide(ru, r_out, out=np.ones_like(r_out), where=r_out > 0)
        warped = geometry.radial_resample(radiance[..., b], dx, scale)
        radiance[..., b] = np.where(outside, 0.0, warped) * np.tensordot(band_w[:, b], gain, axes=1)
    irr_sharp = radiance * params.transmittance

    # PSF grid: shares by zone × azimuth, each convolved with its oriented PSF
    zones, psfs, size = tab["zones"], tab["psfs"], tab["size"]
    azimuths = np.arange(params.psf_azimuths) * 2 * np.pi / params.psf_azimuths
    zone_w = hat_weights(r_out, zones)
    az_w = hat_weights(np.arctan2(x, y), azimuths, periodic=True)
    pad = fourier.pad_width((rows, cols), size)
    pshape = (fft.next_fast_len(rows + 2 * pad, real=True), fft.next_fast_len(cols + 2 * pad, real=True))
    acc = np.zeros((n_bands, pshape[0], pshape[1] // 2 + 1), np.complex128)
    for z_i in range(zones.size):
        terms = [(0.0, zone_w[z_i])] if z_i == 0 else [(a, zone_w[z_i] * az_w[a_i]) for a_i, a in enumerate(azimuths)]
        for angle, weight in terms:
            if not weight.any():
                continue
            node_otf = [fourier.kernel_otf(_oriented(psfs[z_i, n_i], angle), pshape) for n_i in range(nodes.size)]
            for b in range(n_bands):
                part = np.pad(irr_sharp[..., b] * weight,
                              ((pad, pshape[0] - rows - pad), (pad, pshape[1] - cols - pad)), mode="symmetric")
                otf = sum(band_w[n_i, b] * node_otf[n_i] for n_i in range(nodes.size) if band_w[n_i, b])
                acc[b] += fft.rfft2(part, workers=-1) * otf
    out = np.empty_like(irr_sharp)
    clipped = 0
    for b in range(n_bands):
        plane = fft.irfft2(acc[b], s=pshape, workers=-1)[pad:pad + rows, pad:pad + cols]
        clipped += int((plane < 0).sum())
        out[..., b] = np.maximum(plane, 0.0)
    return OpticalImage(pinhole.check_finite("psf_grid", out), wl.copy(), dx, pdata.efl_mm * 1e-3,
                        float(pdata.f_number), depth_m=scene.depth_m,
                        meta={"model": "psf_grid", "image_distance_m": d_img, "lens": lens.name,
                              "zones_m": zones.tolist(), "psf_wavelengths_nm": nodes.tolist(),
                              "psf_size": size, "azimuths": params.psf_azimuths,
                              "clipped_fraction": clipped / out.size, "focal_length_m": pdata.efl_mm * 1e-3})


register_optics("psf_grid")(radiance_to_irradiance)

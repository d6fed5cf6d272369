"""Level 3: field × wavelength × depth PSF grid of a real lens, with its distortion and illumination.

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
5. depth: when the scene's axial depths (thin_lens.axial_depth_m) spread the paraxial blur
   circle by more than thin_lens.FLAT_BLUR_SAMPLES, the PSF grid is traced at `psf_depth_nodes`
   object distances evenly spaced in 1/z (defocus grows with |1/z − 1/s|), the focus distance
   always a node when inside the range (blur is not linear across focus; PSFs are geometric past
   GEOMETRIC_DEFOCUS_WAVES of defocus, where the pupil phase is too steep), and every sample's light
   is split linearly in 1/z between the two nodes that bracket it, as thin_lens splits by blur
   (shares sum to 1, so light is conserved; occlusion at depth edges is not modelled). A flat
   scene is one node at its depth, the focus distance for a scene in focus. Distortion and
   radiometry stay those traced at the focus distance: the exit-pupil irradiance integral does
   not depend on the object distance, the chief ray's landing point only through the small
   parallax between the first vertex and the entrance pupil.
"""
from __future__ import annotations

import itertools
import math
from functools import lru_cache

import numpy as np
from scipy import fft, ndimage

from workbench.errors import InvalidValueError, check_finite
from workbench.optics.formation import fourier, geometry, lens_setup, thin_lens
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
    if not k.sum() > 0:                  # the spot missed the grid (sized by in-focus spots): far out of focus
        raise InvalidValueError(
            f"optics psf_grid: the lens's PSF falls outside its {k.shape[0]}×{k.shape[1]}-sample grid: the scene is "
            "far out of focus for this model; set optics.focus_distance_m near scene.distance_m (or null: focused on "
            "the scene), or use the 'raytrace' or 'thin_lens' model, which follow any defocus")
    return k / k.sum()


GEOMETRIC_DEFOCUS_WAVES = 32.0   # psf_diffraction's 512-sample pupil resolves the phase up to ~64


@lru_cache(maxsize=8)
def lens_tables(lens, object_distance_m: float, image_distance: float, r_max_m: float,
                nodes_nm: tuple[float, ...]) -> dict:
    """Traced geometry of a focused lens, cached: 'ru'/'rd' (per wavelength node): pinhole
    height → real chief-ray height (m); 'heights', 'e': irradiance per radiance against height.
    The pinhole sits at the entrance pupil, but a traced field angle is measured at the first
    vertex, `object_distance_m` from the object: each angle is widened so that both aim at the
    same object point."""
    from workbench.optics.lens import chief_ray_on_sensor, paraxial
    ru_table = np.linspace(0.0, max(r_max_m * 1.3, 0.02 * image_distance), 25)
    vertex_tan = 1.0 if math.isinf(object_distance_m) else \
        1.0 + paraxial(lens).entrance_pupil_mm * 1e-3 / object_distance_m
    ru, rd, e = [], [], []
    for wl_n in nodes_nm:
        hs = []
        for r_u in ru_table:
            try:
                hs.append(chief_ray_on_sensor(lens, math.degrees(math.atan(vertex_tan * r_u / image_distance)),
                                              wl_n, object_distance_m)[1] * 1e-3)
            except ValueError:
                break
        if len(hs) < 2 or np.any(np.diff(hs) <= 0):
            raise InvalidValueError(f"psf_grid: lens {lens.name!r} does not image the field monotonically "
                             f"at {wl_n:.0f} nm (chief rays traced to {len(hs)} heights)")
        ru.append(ru_table[:len(hs)])
        rd.append(np.array(hs))
        heights_mm, e_n = lens_setup.irradiance_table(lens, r_max_m * 1e3, wl_n)
        e.append(e_n)
    return {"ru": ru, "rd": rd, "heights": heights_mm * 1e-3, "e": np.array(e)}


@lru_cache(maxsize=32)
def psf_table(lens, object_distance_m: float, image_distance: float, r_max_m: float,
              nodes_nm: tuple[float, ...], n_zones: int, spacing_m: float, defocus_coc_m: float = 0.0) -> dict:
    """PSFs of a focused lens for an object at `object_distance_m` (from the first vertex),
    cached per lens, focus and object distance (the expensive part of this level):
    'zones' (m), 'psfs' (zones × wavelength nodes × size²), 'size'. Wave-optical PSFs, except
    geometric ones (binned rays) where the paraxial defocus blur `defocus_coc_m` holds more than
    GEOMETRIC_DEFOCUS_WAVES waves of defocus: there the pupil phase is too steep to sample and
    diffraction changes the PSF by less than a percent."""
    from workbench.optics.lens import paraxial, psf_diffraction, psf_geometric
    zones = np.linspace(0.0, r_max_m, n_zones)
    f_number = paraxial(lens).f_number
    max_field = math.degrees(math.atan(r_max_m / image_distance))
    size = _psf_size(lens, f_number, max(nodes_nm), max_field, spacing_m * 1e6, object_distance_m)
    psfs = np.zeros((zones.size, len(nodes_nm), size, size))
    for z_i, h in enumerate(zones):
        for n_i, wl_n in enumerate(nodes_nm):
            waves = defocus_coc_m / (8.0 * f_number * wl_n * 1e-9)        # W020 = c/(8N), in waves
            psf = psf_geometric if waves > GEOMETRIC_DEFOCUS_WAVES else psf_diffraction
            try:
                psfs[z_i, n_i] = psf(lens, float(h) * 1e3, wl_n, object_distance_m, spacing_m * 1e6, size)
            except ValueError:
                psfs[z_i, n_i] = psfs[z_i - 1, n_i] if z_i else 0.0   # vignetted: reuse the inner zone
    return {"zones": zones, "psfs": psfs, "size": size}


def depth_nodes_inv_m(inv_depth_per_m: np.ndarray, inv_focus_per_m: float, count: int,
                      coc_per_inv_m: float, spacing_m: float) -> np.ndarray:
    """Ascending object-distance nodes as inverse distances 1/z (1/m) covering the scene's 1/z.

    One node when count is 1 or the paraxial blur circle, coc_per_inv_m·|1/z − 1/s|, spreads
    less than thin_lens.FLAT_BLUR_SAMPLES over the scene: the focus if inside the range or that
    close to every depth (a scene in focus), else the middle. Otherwise `count` nodes evenly
    spaced from the farthest to the nearest depth; when the focus lies inside, both ends and a
    grid of step range/(count − 2) through the focus (at least 3 nodes, one more than count
    when the focus is within a quarter step of an end)."""
    lo, hi = float(inv_depth_per_m.min()), float(inv_depth_per_m.max())
    if count == 1 or not thin_lens.depth_varies(coc_per_inv_m * (hi - lo), spacing_m):
        in_focus = not thin_lens.depth_varies(coc_per_inv_m * max(abs(lo - inv_focus_per_m),
                                                                  abs(hi - inv_focus_per_m)), spacing_m)
        return np.array([inv_focus_per_m if in_focus or lo <= inv_focus_per_m <= hi else 0.5 * (lo + hi)])
    if not lo < inv_focus_per_m < hi:
        return np.linspace(lo, hi, count)
    step = (hi - lo) / max(count - 2, 1)
    k = np.arange(math.floor((lo - inv_focus_per_m) / step), math.ceil((hi - inv_focus_per_m) / step) + 1)
    grid = inv_focus_per_m + k * step
    inner = np.union1d(grid[(grid > lo + 0.25 * step) & (grid < hi - 0.25 * step)], [inv_focus_per_m])
    return np.concatenate([[lo], inner, [hi]])


def _axial_depth_checked(scene: Scene, spacing_m: float, image_distance: float, focal_length_m: float) -> np.ndarray:
    """thin_lens.axial_depth_m, with a clear error for depths the lens cannot image."""
    z = thin_lens.axial_depth_m(scene, spacing_m, image_distance)
    bad = ~(z > focal_length_m)
    if bad.any():
        raise InvalidValueError(f"psf_grid: scene depth_m must exceed the lens's focal length {focal_length_m:.4g} m "
                         f"(axial; inf allowed, NaN not) at every sample; {int(bad.sum())} samples do not, "
                         f"e.g. {float(z[bad][0]):.4g} m")
    return z


def radiance_to_irradiance(scene: Scene, params: OpticsParams,
                           camera: geometry.CameraGeometry | None = None) -> OpticalImage:
    """Irradiance through params.lens_file by a field/wavelength/depth PSF grid (see module doc)."""
    from workbench.optics.lens import paraxial
    g = geometry.scene_geometry(scene, params, camera)
    s_m, d_img, dx = g.focus_distance_m, g.image_distance_m, g.sample_spacing_m
    lens, obj_m = lens_setup.focused_lens(params, s_m)
    pdata = paraxial(lens)
    radiance = scene.radiance_photons.astype(np.float64)           # on the pinhole's grid
    rows, cols, n_bands = radiance.shape
    x, y = geometry.sample_positions_m((rows, cols), dx)
    r_out = np.hypot(x, y)
    r_max = float(r_out.max()) * 1.0001
    wl = scene.wavelengths_nm
    nodes = _wavelength_nodes(wl, params.psf_wavelengths)
    band_w = hat_weights(wl, nodes)                              # nodes × bands
    nodes_key = tuple(float(v) for v in nodes)
    tab = lens_tables(lens, obj_m, d_img, r_max, nodes_key)
    inv_z = 1.0 / _axial_depth_checked(scene, dx, d_img, pdata.efl_mm * 1e-3)
    inv_s = 0.0 if math.isinf(s_m) else 1.0 / s_m
    coc_per_inv_m = thin_lens.coc_scale_m(pdata.efl_mm * 1e-3, pdata.f_number, s_m)
    inv_nodes = depth_nodes_inv_m(inv_z, inv_s, params.psf_depth_nodes, coc_per_inv_m, dx)
    depth_nodes_m = [s_m if u == inv_s else (math.inf if u == 0 else 1.0 / float(u)) for u in inv_nodes]
    psf_tabs = [psf_table(lens, obj_m, d_img, r_max, nodes_key, params.psf_field_zones, dx) if z == s_m else
                psf_table(lens, lens_setup.focused_lens(params, z)[1], d_img, r_max, nodes_key,
                          params.psf_field_zones, dx, coc_per_inv_m * abs(float(u) - inv_s))
                for z, u in zip(depth_nodes_m, inv_nodes)]

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
    if inv_nodes.size > 1:       # the depth map follows the light (mid wavelength node's distortion)
        mid = nodes.size // 2
        scale = np.divide(np.where(np.isfinite(ru_at_out[mid]), ru_at_out[mid], 0.0), r_out,
                          out=np.ones_like(r_out), where=r_out > 0)
        inv_z = np.clip(geometry.radial_resample(inv_z, dx, scale), inv_nodes[0], inv_nodes[-1])
    depth_w = thin_lens.layer_weights(inv_z, inv_nodes)          # depth nodes × H × W

    # PSF grid: shares by zone × azimuth, each convolved with its oriented PSF
    zones = psf_tabs[0]["zones"]
    size = max(t["size"] for t in psf_tabs)
    azimuths = np.arange(params.psf_azimuths) * 2 * np.pi / params.psf_azimuths
    zone_w = hat_weights(r_out, zones)
    az_w = hat_weights(np.arctan2(x, y), azimuths, periodic=True)
    pad = fourier.pad_width((rows, cols), size)
    pshape = (fft.next_fast_len(rows + 2 * pad, real=True), fft.next_fast_len(cols + 2 * pad, real=True))
    acc = np.zeros((n_bands, pshape[0], pshape[1] // 2 + 1), np.complex128)
    for d_i, z_i in itertools.product(range(len(psf_tabs)), range(zones.size)):
        psfs = psf_tabs[d_i]["psfs"]
        terms = [(0.0, zone_w[z_i])] if z_i == 0 else [(a, zone_w[z_i] * az_w[a_i]) for a_i, a in enumerate(azimuths)]
        for angle, weight in terms:
            weight = weight * depth_w[d_i]                 # × 1.0 (exact) for a single node
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
    return OpticalImage(check_finite("optics psf_grid", out).astype(np.float32), wl.copy(), dx, pdata.efl_mm * 1e-3,
                        float(pdata.f_number), depth_m=scene.depth_m,
                        meta={"model": "psf_grid", "image_distance_m": d_img, "lens": lens.name,
                              "zones_m": zones.tolist(), "psf_wavelengths_nm": nodes.tolist(),
                              "psf_size": size, "azimuths": params.psf_azimuths,
                              "focus_distance_m": s_m, "depth_nodes_m": depth_nodes_m,
                              "clipped_fraction": clipped / out.size, "focal_length_m": pdata.efl_mm * 1e-3})


register_optics("psf_grid")(radiance_to_irradiance)

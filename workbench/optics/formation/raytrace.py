"""Level 5 (analytic scenes): sequential real-ray tracing from every sensor sample.

For each output sample, `rays_per_sample` rays leave the sample's centre (an output sample is
the irradiance at a point; a scene sample is a uniform patch, see geometry.radial_resample)
towards the rear lens vertex plane, on a regular grid inside PBRT's exit-pupil box for that field
radius (rotated to the point's azimuth; the same pattern for every sample, so errors are
smooth over the image rather than noise), are traced backwards through the lens, and meet the scene
plane at the scene distance (measured from the entrance pupil, like the pinhole's). Each ray
carries PBRT's realistic-camera weight w = cos⁴θ · A_box / (n · z_rear²); rays that miss an
aperture or suffer TIR carry none. The irradiance is T · (Σ L w / Σ w) · E/L(r): the rays'
weighted mean radiance times the same camera-equation integral Σ w traced densely
(lens_setup.irradiance_table) — a ratio estimator, so a uniform field
carries no sampling error and the few rays per sample only shape the blur. Diffraction is
then added by convolving with the Airy pattern of the working f-number integrated over each
sample cell (diffraction.airy_cell_kernel, the same convention as the PSF grid's
pixel-integrated PSFs): geometric blur ⊛ Airy, an approximation that holds when either
dominates (raytrace_diffraction=False turns it off).
The image is upright: output sample (x, y) is the sensor point (−x, −y).
Dispersive lenses are traced once per wavelength, non-dispersive ones once.
"""
from __future__ import annotations

import math

import numpy as np

from workbench.errors import check_finite
from workbench.optics.formation import diffraction, fourier, geometry, lens_setup
from workbench.optics.params import OpticsParams
from workbench.optics.types import OpticalImage, register_optics
from workbench.scene.types import Scene

_CHUNK_RAYS = 200_000
_RADIAL_BINS = 32


def _is_dispersive(lens, wavelengths_nm: np.ndarray) -> bool:
    wl = np.array([wavelengths_nm.min(), wavelengths_nm.max()])
    return any(np.ptp(np.atleast_1d(s.material.index(wl))) > 0 for s in lens.surfaces)


def _pupil_boxes(lens, max_radius_mm: float, wavelength_nm: float):
    """Exit-pupil box (x0, x1, y0, y1) per radial bin, for sensor points on +y (None = blocked)."""
    from workbench.optics.lens.analysis import rear_pupil_box
    edges = np.linspace(0.0, max_radius_mm * 1.0001, _RADIAL_BINS + 1)
    at_edge = [rear_pupil_box(lens, float(h), wavelength_nm) for h in edges]
    boxes = []
    for a, b in zip(at_edge[:-1], at_edge[1:]):
        have = [x for x in (a, b) if x is not None]
        boxes.append(None if not have else (min(x[0] for x in have), max(x[1] for x in have),
                                            min(x[2] for x in have), max(x[3] for x in have)))
    return edges, boxes


def _pupil_grid(n: int) -> np.ndarray:
    """n points in [0,1)²: the centres of the first n cells of a ⌈√n⌉² grid, the same for every
    sample, so the estimate varies smoothly across the image instead of as per-sample noise."""
    side = int(math.ceil(math.sqrt(n)))
    cells = np.arange(n)
    return (np.stack([cells % side, cells // side], axis=-1) + 0.5) / side


def _scene_lookup(radiance: np.ndarray, fov_deg: float, x_mm: np.ndarray, y_mm: np.ndarray,
                  plane_distance_mm: float) -> np.ndarray:
    """Radiance (N × C) of an H×W×C scene spanning fov_deg at points of the object plane
    `plane_distance_mm` from the entrance pupil: each scene sample is a uniform square patch
    (its radiance is the patch average); up to one patch beyond the border the edge patch
    continues (the frame's outermost cells reach past the scene under barrel distortion), 0
    farther out."""
    rows, cols = radiance.shape[:2]
    half_w = plane_distance_mm * math.tan(math.radians(fov_deg) / 2.0)
    pitch = 2.0 * half_w / cols
    u = np.floor(x_mm / pitch + cols / 2.0).astype(np.int64)
    v = np.floor(rows / 2.0 - y_mm / pitch).astype(np.int64)
    inside = (u >= -1) & (u <= cols) & (v >= -1) & (v <= rows)
    out = radiance[np.clip(v, 0, rows - 1), np.clip(u, 0, cols - 1)]
    return np.where(inside[:, None], out, 0.0)


def radiance_to_irradiance(scene: Scene, params: OpticsParams,
                           camera: geometry.CameraGeometry | None = None) -> OpticalImage:
    """Irradiance on the sensor by tracing rays through params.lens_file (see module doc)."""
    from workbench.optics.lens.paraxial import paraxial, sensor_z_mm
    from workbench.optics.lens.trace import trace_rays

    g = geometry.scene_geometry(scene, params, camera)
    lens, _ = lens_setup.focused_lens(params, g.focus_distance_m)
    pdata = paraxial(lens)
    f_m, d_img, dx = g.focal_length_m, g.image_distance_m, g.sample_spacing_m
    n_w = float(pdata.f_number) * d_img / f_m
    if params.raytrace_diffraction:         # refuse an unbuildable Airy kernel before tracing
        diffraction.check_airy_kernel(float(scene.wavelengths_nm.max()) * 1e-9, n_w, dx)
    rows, cols = scene.shape
    x, y = geometry.sample_positions_m((rows, cols), dx)
    px, py = -x.ravel() * 1e3, -y.ravel() * 1e3           # physical sensor points (inverted), mm
    radius = np.hypot(px, py)
    wl_all = scene.wavelengths_nm
    dispersive = _is_dispersive(lens, wl_all)
    edges, boxes = _pupil_boxes(lens, float(radius.max()), float(np.median(wl_all)))
    z_sensor, z_rear = sensor_z_mm(lens), lens.total_track_mm
    z_obj = pdata.entrance_pupil_mm - scene.distance_m * 1e3
    bin_of = np.clip(np.searchsorted(edges, radius, side="right") - 1, 0, _RADIAL_BINS - 1)
    n = params.rays_per_sample
    irr = np.zeros((rows * cols, wl_all.size))
    wsum = np.zeros((rows * cols, wl_all.size if dispersive else 1))
    per_chunk = max(1, _CHUNK_RAYS // n)
    grid = _pupil_grid(n)
    for start in range(0, rows * cols, per_chunk):
        idx = np.arange(start, min(start + per_chunk, rows * cols))
        boxes_c = [boxes[b] for b in bin_of[idx]]
        live = np.array([b is not None for b in boxes_c])
        if not live.any():
            continue
        idx, boxes_c = idx[live], [b for b in boxes_c if b is not None]
        box = np.array(boxes_c)                                           # m × 4
        uv = np.broadcast_to(grid, (idx.size, n, 2))                      # m × n × 2
        bx = box[:, None, 0] + uv[..., 0] * (box[:, None, 1] - box[:, None, 0])
        by = box[:, None, 2] + uv[..., 1] * (box[:, None, 3] - box[:, None, 2])
        area = (box[:, 1] - box[:, 0]) * (box[:, 3] - box[:, 2])
        # rotate the +y box to the sample's azimuth
        ang = np.arctan2(px[idx], py[idx])
        c, s = np.cos(ang)[:, None], np.sin(ang)[:, None]
        tx, ty = c * bx + s * by, -s * bx + c * by
        src = np.stack([np.repeat(px[idx], n), np.repeat(py[idx], n), np.full(idx.size * n, z_sensor)], 1)
        d = np.stack([tx.ravel(), ty.ravel(), np.full(idx.size * n, z_rear)], 1) - src
        d /= np.linalg.norm(d, axis=1)[:, None]
        weight = (d[:, 2] ** 4).reshape(idx.size, n) * (area / (n * (z_sensor - z_rear) ** 2))[:, None]
        for k, wl in enumerate(wl_all if dispersive else wl_all[:1]):
            tr = trace_rays(lens, src, d, float(wl), reverse=True)
            dz = tr.dirs[:, 2]
            ok = tr.valid & (dz < -1e-12)
            t = np.where(ok, (z_obj - tr.points[:, 2]) / np.where(ok, dz, -1.0), 0.0)
            hx = tr.points[:, 0] + t * tr.dirs[:, 0]
            hy = tr.points[:, 1] + t * tr.dirs[:, 1]
            w = np.where(ok.reshape(idx.size, n), weight, 0.0)
            bands = slice(k, k + 1) if dispersive else slice(None)
            lk = _scene_lookup(scene.radiance_photons[..., bands], scene.fov_deg, hx, hy,
                               scene.distance_m * 1e3)
            irr[idx, bands] += (lk.reshape(idx.size, n, -1) * w[..., None]).sum(1)
            wsum[idx, k] += w.sum(1)
    # ratio estimator: the rays' weighted mean radiance × the densely traced E/L at that radius
    mean_radiance = np.divide(irr, wsum, out=np.zeros_like(irr), where=wsum > 0)
    e_per_l = np.stack([np.interp(radius, *lens_setup.irradiance_table(lens, float(radius.max()) * 1.0001, wl))
                        for wl in (wl_all if dispersive else wl_all[:1])], axis=1)
    irr = (mean_radiance * e_per_l).reshape(rows, cols, -1) * params.transmittance
    clipped = 0.0
    if params.raytrace_diffraction:
        for b, wl in enumerate(wl_all):
            kernel = diffraction.airy_cell_kernel(wl * 1e-9, n_w, dx)
            irr[..., b:b + 1], frac = fourier.apply_otf(irr[..., b:b + 1], dx, lambda c, fy, fx: 1.0,
                                                       fourier.pad_width((rows, cols), kernel.shape[0]), kernel)
            clipped = max(clipped, frac)
    return OpticalImage(check_finite("optics raytrace", irr).astype(np.float32), wl_all.copy(), dx, float(f_m), float(pdata.f_number),
                        depth_m=scene.depth_m,
                        meta={"model": "raytrace", "image_distance_m": float(d_img), "lens": lens.name,
                              "rays_per_sample": n, "dispersive": dispersive,
                              "sensor_distance_mm": float(z_sensor - z_rear), "focal_length_m": float(f_m),
                              "diffraction": params.raytrace_diffraction, "working_f_number": n_w,
                              "clipped_fraction": clipped})


register_optics("raytrace")(radiance_to_irradiance)

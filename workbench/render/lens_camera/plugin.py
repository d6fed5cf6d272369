"""The Mitsuba sensor plugin `workbench_lens`: a `mi.Sensor` that traces every camera ray through a
workbench Lens (see the package docstring for the algorithm, weights and camera frame).

`lens_sensor_dict` prepares a lens (pupil boxes, constants) under a key that the plugin instance
looks up when Mitsuba loads the dict; each instance keeps its own prepared data.
"""
from __future__ import annotations

import itertools
import threading
from collections import OrderedDict
import math

import numpy as np

from workbench.errors import InvalidValueError
from workbench.optics.lens.glass import LINE_D_NM
from workbench.optics.lens.model import Lens
from workbench.optics.lens.paraxial import paraxial, sensor_z_mm
from workbench.optics.lens.pupil_bins import N_BINS, pupil_bins
from workbench.render.lens_camera.kernels import index_expr, is_dispersive, trace_reverse

PLUGIN_NAME = "workbench_lens"

CAMERA_CACHE_SIZE = 32
_LENSES: dict[str, dict] = {}       # key → prepared lens data, looked up by the plugin
_KEYS: OrderedDict[tuple, str] = OrderedDict()   # camera → key, the CAMERA_CACHE_SIZE latest
_CACHE_LOCK = threading.Lock()
_counter = itertools.count()
_registered: set[str] = set()


def _make_sensor_class(mi, dr):
    class LensSensor(mi.Sensor):
        """Mitsuba sensor tracing through a workbench Lens (see workbench.render.lens_camera)."""

        def __init__(self, props):
            mi.Sensor.__init__(self, props)
            key = props.get("lens_key")
            if key not in _LENSES:
                raise InvalidValueError(f"{PLUGIN_NAME}: unknown lens_key {key!r}; build the dict with "
                                 "lens_sensor_dict()")
            self.data = _LENSES[key]
            self.m_needs_sample_3 = True

        def sample_ray(self, time, sample1, sample2, sample3, active=True):
            d = self.data
            lens: Lens = d["lens"]
            wavelengths, wav_weight = self.sample_wavelengths(dr.zeros(mi.SurfaceInteraction3f),
                                                              sample1, active)
            wl = wavelengths[0] if d["dispersive"] else None
            # Film point in lens coordinates (image inverted: film x = −camera x).
            fx = -(sample2.x - 0.5) * d["width_mm"]
            fy = (sample2.y - 0.5) * d["height_mm"]
            r = dr.sqrt(fx * fx + fy * fy)
            nb = d["n_bins"]
            b = mi.UInt32(dr.minimum(r * (nb / d["max_radius_mm"]), nb - 1))
            cx = dr.gather(mi.Float, d["box_cx"], b)
            cy = dr.gather(mi.Float, d["box_cy"], b)
            hx = dr.gather(mi.Float, d["box_hx"], b)
            hy = dr.gather(mi.Float, d["box_hy"], b)
            area = dr.gather(mi.Float, d["box_area"], b)
            # A point of the bin's inscribed ellipse (where pupil_bins found that it holds the pupil)
            # or of its box; the label cast's sample (½, ½) is the centre either way.
            disk = mi.warp.square_to_uniform_disk_concentric(sample3)
            ell = dr.gather(mi.Bool, d["box_ellipse"], b)
            bx = cx + hx * dr.select(ell, disk.x, dr.fma(2.0, sample3.x, -1.0))
            by = cy + hy * dr.select(ell, disk.y, dr.fma(2.0, sample3.y, -1.0))
            # Rotate the box from +y to the film point's azimuth.
            safe = r > 1e-12
            cs = dr.select(safe, fy / dr.select(safe, r, 1.0), 1.0)
            sn = dr.select(safe, -fx / dr.select(safe, r, 1.0), 0.0)
            tx, ty = bx * cs - by * sn, bx * sn + by * cs
            zs, zr = d["sensor_z_mm"], d["rear_z_mm"]
            dx, dy, dz = tx - fx, ty - fy, mi.Float(zr - zs)
            inv = dr.rsqrt(dx * dx + dy * dy + dz * dz)
            dx, dy, dz = dx * inv, dy * inv, dz * inv
            cos_t = -dz
            px, py, pz, ox, oy, oz, ok = trace_reverse(lens, fx, fy, mi.Float(zs), dx, dy, dz, wl, dr, mi)
            ok &= area > 0.0
            cos2 = cos_t * cos_t
            w = dr.select(ok, cos2 * cos2 * area * (d["scale"] / (zs - zr) ** 2), 0.0)
            # Lens → camera frame (origin at the entrance pupil, +z towards the scene). A ray that
            # dies carries no weight; it leaves the entrance pupil along the paraxial chief ray of
            # its film point, so casts through this sensor (labels, depth) still see that pixel.
            ep = d["entrance_pupil_z_mm"]
            o = mi.Point3f(dr.select(ok, -px, 0.0), dr.select(ok, py, 0.0), dr.select(ok, ep - pz, 0.0)) * 1e-3
            v = dr.select(ok, mi.Vector3f(-ox, oy, -oz),
                          dr.normalize(mi.Vector3f(fx, -fy, d["chief_image_distance_mm"])))
            ray = mi.Ray3f(self.world_transform() @ o, self.world_transform() @ v, time, wavelengths)
            if d["dispersive"]:
                weight = mi.Spectrum(4.0 * w, 0.0, 0.0, 0.0) * wav_weight
            else:
                weight = wav_weight * w
            return ray, dr.select(active, weight, 0.0)

        def sample_ray_differential(self, time, sample1, sample2, sample3, active=True):
            ray, weight = self.sample_ray(time, sample1, sample2, sample3, active)
            return mi.RayDifferential3f(ray), weight

        def to_string(self):
            return f"LensSensor[{self.data['lens'].name}]"

    return LensSensor


def register_lens_sensor() -> str:
    """Register the plugin for the current Mitsuba variant (idempotent); returns its name."""
    import drjit as dr
    import mitsuba as mi
    variant = mi.variant()
    if variant is None:
        raise InvalidValueError("Mitsuba has no variant set; call workbench.render.variants.select_variant() first")
    if variant not in _registered:
        cls = _make_sensor_class(mi, dr)
        mi.register_sensor(PLUGIN_NAME, lambda props: cls(props))
        _registered.add(variant)
    return PLUGIN_NAME


def lens_sensor_dict(lens: Lens, film_dict: dict, to_world, sensor_width_mm: float,
                     sampler: dict | None = None, weight: str = "irradiance",
                     n_bins: int = N_BINS, dispersion: bool = True) -> dict:
    """A Mitsuba sensor dict for mi.load_dict: `lens` (at its current focus) with a film of
    `sensor_width_mm` across film_dict's width (square pixels); to_world as for a perspective
    camera (placed at the entrance pupil); scene units are metres.
    weight: 'irradiance' (film = camera-equation irradiance per unit radiance) or 'radiance'
    (normalised so a uniform scene reads its radiance at the centre).
    dispersion: trace the hero wavelength through dispersive glass (False: every ray at the d line,
    no chromatic noise, no colour aberrations)."""
    if weight not in ("irradiance", "radiance"):
        raise InvalidValueError(f"weight={weight!r}: allowed 'irradiance' or 'radiance'")
    if not (math.isfinite(sensor_width_mm) and sensor_width_mm > 0):
        raise InvalidValueError(f"sensor_width_mm={sensor_width_mm}: must be a finite number > 0")
    try:
        w_px, h_px = int(film_dict["width"]), int(film_dict["height"])
    except (KeyError, TypeError, ValueError):
        raise InvalidValueError("film_dict: needs integer 'width' and 'height'") from None
    import drjit as dr
    import mitsuba as mi
    if str(mi.variant()).startswith("scalar"):
        raise InvalidValueError(f"the Mitsuba lens camera needs a JIT variant (llvm_ad_spectral or cuda_ad_spectral), "
                         f"not {mi.variant()!r}")
    name = register_lens_sensor()
    dispersive = dispersion and is_dispersive(lens)
    if dispersive:
        for s in lens.surfaces:
            index_expr(s.material, mi.Float(LINE_D_NM), dr, mi)  # refuse tables early
    width_mm = float(sensor_width_mm)
    height_mm = width_mm * h_px / w_px
    max_r = 0.5 * math.hypot(width_mm, height_mm)
    edges, boxes, ellipse = pupil_bins(lens, max_r, n_bins)
    half_x, half_y = (boxes[:, 1] - boxes[:, 0]) / 2, (boxes[:, 3] - boxes[:, 2]) / 2
    zs, zr = sensor_z_mm(lens), lens.total_track_mm
    scale = 1.0
    if weight == "radiance":
        from workbench.optics.lens.analysis import irradiance_per_radiance
        e0 = irradiance_per_radiance(lens, 0.0)
        if e0 <= 0:
            raise InvalidValueError(f"lens {lens.name!r}: no ray reaches the centre of the sensor")
        scale = 1.0 / e0
    pdata = paraxial(lens)
    ident = (lens, width_mm, height_mm, n_bins, dispersive, float(scale))
    with _CACHE_LOCK:                     # the same camera reuses its entry; the oldest go
        key = _KEYS.pop(ident, None) or f"lens{next(_counter)}"
        _KEYS[ident] = key
        while len(_KEYS) > CAMERA_CACHE_SIZE:
            _LENSES.pop(_KEYS.popitem(last=False)[1], None)
    _LENSES[key] = {
        "lens": lens, "dispersive": dispersive, "width_mm": width_mm, "height_mm": height_mm,
        "max_radius_mm": float(edges[-1]), "n_bins": n_bins,
        "box_cx": mi.Float((boxes[:, 0] + boxes[:, 1]) / 2), "box_cy": mi.Float((boxes[:, 2] + boxes[:, 3]) / 2),
        "box_hx": mi.Float(half_x), "box_hy": mi.Float(half_y), "box_ellipse": mi.Bool(ellipse),
        "box_area": mi.Float(np.where(ellipse, math.pi, 4.0) * half_x * half_y),
        "sensor_z_mm": float(zs), "rear_z_mm": float(zr), "scale": float(scale),
        "entrance_pupil_z_mm": float(pdata.entrance_pupil_mm),
        "chief_image_distance_mm": float(zs - zr - pdata.bfl_mm + pdata.efl_mm),
    }
    out = {"type": name, "lens_key": key, "to_world": to_world, "film": film_dict}
    if sampler is not None:
        out["sampler"] = sampler
    return out

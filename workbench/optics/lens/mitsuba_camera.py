"""The real lens inside Mitsuba 3: a Python `mi.Sensor` that traces every camera ray through the lens.

Algorithm (PBRT's realistic camera): the film sample gives a point on the sensor plane; the aperture
sample picks a point in the exit-pupil box of that point's radial bin (boxes precomputed in numpy
and cached per lens, focus and film size); the ray from the film point to that point is traced
backwards through every surface with Dr.Jit arithmetic (vertex-relative intersection, Snell, masks
for misses and TIR); its weight is cos⁴θ · A_box / z_rear² (0 for rays that die, which get a
harmless direction). With `weight="irradiance"` the film then holds E = ∫ L cos⁴θ / z² dA, the
camera equation (π L /(4N²) on axis for a uniform scene); with `weight="radiance"` it is divided
by the on-axis value so a uniform scene reads L at the centre, as with the perspective camera.

Dispersive lenses trace the hero wavelength of Mitsuba's four spectral samples (weight 4 on it,
0 on the others); non-dispersive lenses trace once at the d line for all four.

Camera frame: the origin is the lens's entrance pupil, +z looks at the scene, +y is image-up and
+x image-left (as Mitsuba's perspective camera), so `to_world` is placed like a pinhole's.
The variant must be set before `lens_sensor_dict` is called (see workbench.render.variants); it must
be a JIT variant (llvm/cuda): the scalar variants would call Python once per sample.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from workbench.optics.lens.analysis import rear_pupil_box
from workbench.optics.lens.glass import LINE_D_NM, Material
from workbench.optics.lens.model import Lens
from workbench.optics.lens.paraxial import paraxial, sensor_z_mm

PLUGIN_NAME = "workbench_lens"
N_BINS = 32

_LENSES: dict[str, dict] = {}       # key → prepared lens data, looked up by the plugin
_BOX_CACHE: dict[tuple, tuple] = {}
_counter = itertools.count()
_registered: set[str] = set()


def pupil_bins(lens: Lens, max_radius_mm: float, n_bins: int = N_BINS,
               wavelength_nm: float = LINE_D_NM) -> tuple[np.ndarray, np.ndarray]:
    """Exit-pupil boxes per radial bin of the film: (edges (n+1,), boxes (n, 4) as x0, x1, y0, y1
    on the rear-vertex plane for film points on +y; an all-zero box where no ray passes). Cached."""
    key = (lens, round(max_radius_mm, 9), n_bins, wavelength_nm)
    if key in _BOX_CACHE:
        return _BOX_CACHE[key]
    edges = np.linspace(0.0, max_radius_mm * 1.0001, n_bins + 1)
    at = [rear_pupil_box(lens, float(h), wavelength_nm) for h in edges]
    boxes = np.zeros((n_bins, 4))
    for i in range(n_bins):
        have = [b for b in (at[i], at[i + 1]) if b is not None]
        if have:
            boxes[i] = (min(b[0] for b in have), max(b[1] for b in have),
                        min(b[2] for b in have), max(b[3] for b in have))
    _BOX_CACHE[key] = (edges, boxes)
    return edges, boxes


def _index_expr(mat: Material, wl, dr, mi):
    """Refractive index as a Dr.Jit expression of wavelength `wl` (nm), or a Python float."""
    if mat.kind == "constant":
        return float(mat.nd)
    lam_um = wl * 1e-3
    if mat.kind == "abbe":
        A, B = mat.cauchy_coefficients()
        return float(A) + float(B) / (lam_um * lam_um)
    if mat.kind == "sellmeier":
        l2 = lam_um * lam_um
        n2 = mi.Float(1.0)
        for k, l in zip(mat.K, mat.L):
            n2 += float(k) * l2 / (l2 - float(l))
        return dr.sqrt(n2)
    raise ValueError(f"material {mat.spec!r}: tabulated indices are not supported in the Mitsuba lens "
                     "camera; use a catalogue glass or 'n/V'")


def _is_dispersive(lens: Lens) -> bool:
    return any(s.material.kind != "constant" for s in lens.surfaces)


def _trace_reverse(lens: Lens, px, py, pz, dx, dy, dz, wl, dr, mi):
    """Trace Dr.Jit rays (lens coordinates, travelling −z) from the sensor to object space at
    wavelength `wl` (a Dr.Jit Float, or None for the d-line indices as constants).
    Returns (px, py, pz, dx, dy, dz, valid)."""
    media = lens.media()
    zv = lens.vertex_z_mm
    valid = mi.Bool(True)
    for i in reversed(range(len(lens.surfaces))):
        s = lens.surfaces[i]
        c, kk = float(s.curvature_per_mm), 1.0 + float(s.conic)
        qz = pz - float(zv[i])
        if c == 0.0:
            t = -qz / dr.select(dr.abs(dz) > 1e-12, dz, 1.0)
            hit = (dr.abs(dz) > 1e-12) & (t >= -1e-9)
        else:
            A = c * (dx * dx + dy * dy + kk * dz * dz)
            b = c * (px * dx + py * dy + kk * qz * dz) - dz
            C = c * (px * px + py * py + kk * qz * qz) - 2.0 * qz
            disc = b * b - A * C
            hit = disc >= 0.0
            sq = dr.sqrt(dr.maximum(disc, 0.0))
            q = -(b + dr.select(b >= 0.0, sq, -sq))
            t1 = C / dr.select(q != 0.0, q, 1.0)
            t2 = q / dr.select(A != 0.0, A, 1.0)
            ok1 = (q != 0.0) & (t1 >= -1e-9) & (kk * c * (qz + t1 * dz) <= 1.0 + 1e-9)
            ok2 = (A != 0.0) & (t2 >= -1e-9) & (kk * c * (qz + t2 * dz) <= 1.0 + 1e-9)
            t = dr.select(ok1 & (~ok2 | (t1 <= t2)), t1, t2)
            hit &= ok1 | ok2
        if s.is_aspheric:
            t, hit = _newton_asphere(s, px, py, qz, dx, dy, dz, dr.select(hit, t, -qz / dr.select(
                dr.abs(dz) > 1e-12, dz, 1.0)), dr)
        px, py, pz = px + t * dx, py + t * dy, pz + t * dz
        valid &= hit & (px * px + py * py <= float(s.semi_aperture_mm) ** 2)
        if wl is None:
            n1, n2 = float(media[i + 1].nd), float(media[i].nd)
        else:
            n1, n2 = _index_expr(media[i + 1], wl, dr, mi), _index_expr(media[i], wl, dr, mi)
        if s.is_stop or (isinstance(n1, float) and isinstance(n2, float) and n1 == n2):
            continue
        if s.is_aspheric:
            _, ds = _sag_dr(s, px * px + py * py, dr)
            nx, ny, nz = -2.0 * px * ds, -2.0 * py * ds, mi.Float(1.0)
        else:
            nx, ny, nz = -c * px, -c * py, 1.0 - c * kk * (pz - float(zv[i]))
        inv = dr.rsqrt(nx * nx + ny * ny + nz * nz)
        nx, ny, nz = nx * inv, ny * inv, nz * inv
        cosi = dx * nx + dy * ny + dz * nz
        sgn = dr.select(cosi >= 0.0, 1.0, -1.0)
        nx, ny, nz, cosi = nx * sgn, ny * sgn, nz * sgn, cosi * sgn
        mu = n1 / n2
        k = 1.0 - mu * mu * (1.0 - cosi * cosi)
        valid &= k >= 0.0
        coef = dr.sqrt(dr.maximum(k, 0.0)) - mu * cosi
        dx, dy, dz = mu * dx + coef * nx, mu * dy + coef * ny, mu * dz + coef * nz   # stays unit length
    return px, py, pz, dx, dy, dz, valid


def _sag_dr(s, rho, dr):
    """Sag and d(sag)/d(r²) of an even asphere as Dr.Jit expressions of rho = r²."""
    c, kk = float(s.curvature_per_mm), 1.0 + float(s.conic)
    root = dr.sqrt(dr.maximum(1.0 - kk * c * c * rho, 0.0))
    sag = c * rho / (1.0 + root)
    dsag = c / (2.0 * dr.maximum(root, 1e-12))
    power = 1.0
    for j, a in enumerate(s.asphere_coeffs):       # a · rho^(j+1); derivative (j+1) a rho^j
        dsag += (j + 1) * float(a) * power
        power = power * rho
        sag += float(a) * power
    return sag, dsag


def _newton_asphere(s, px, py, qz, dx, dy, dz, t, dr, iterations: int = 12):
    """Refine the conic hit t onto the even asphere by Newton's method; returns (t, hit)."""
    for _ in range(iterations):
        x, y, z = px + t * dx, py + t * dy, qz + t * dz
        sag, ds = _sag_dr(s, x * x + y * y, dr)
        fp = dz - 2.0 * ds * (x * dx + y * dy)
        t = t - (z - sag) / dr.select(fp != 0.0, fp, 1.0)
    x, y, z = px + t * dx, py + t * dy, qz + t * dz
    rho = x * x + y * y
    sag, _ = _sag_dr(s, rho, dr)
    c, kk = float(s.curvature_per_mm), 1.0 + float(s.conic)
    tol_mm = 1e-5 * max(1.0, float(s.semi_aperture_mm))   # float32 variants: ~1e-7 relative
    hit = (dr.abs(z - sag) < tol_mm) & (1.0 - kk * c * c * rho >= 0.0) & (t >= -1e-9)
    return t, hit


def _make_sensor_class(mi, dr):
    class LensSensor(mi.Sensor):
        """Mitsuba sensor tracing through a workbench Lens (see the module docstring)."""

        def __init__(self, props):
            mi.Sensor.__init__(self, props)
            key = props.get("lens_key")
            if key not in _LENSES:
                raise ValueError(f"{PLUGIN_NAME}: unknown lens_key {key!r}; build the dict with "
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
            edges_max = d["max_radius_mm"]
            nb = d["n_bins"]
            b = mi.UInt32(dr.minimum(r / edges_max * nb, nb - 1))
            x0 = dr.gather(mi.Float, d["box_x0"], b)
            x1 = dr.gather(mi.Float, d["box_x1"], b)
            y0 = dr.gather(mi.Float, d["box_y0"], b)
            y1 = dr.gather(mi.Float, d["box_y1"], b)
            area = (x1 - x0) * (y1 - y0)
            bx = x0 + sample3.x * (x1 - x0)
            by = y0 + sample3.y * (y1 - y0)
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
            px, py, pz, ox, oy, oz, ok = _trace_reverse(lens, fx, fy, mi.Float(zs), dx, dy, dz, wl, dr, mi)
            ok &= area > 0.0
            w = dr.select(ok, (cos_t * cos_t) * (cos_t * cos_t) * area / ((zs - zr) ** 2), 0.0)
            w = w * d["scale"]
            # Lens → camera frame (origin at the entrance pupil, +z towards the scene).
            o = mi.Point3f(-px, py, d["entrance_pupil_z_mm"] - pz) * 1e-3  # mm → m (scene units)
            v = mi.Vector3f(dr.select(ok, -ox, 0.0), dr.select(ok, oy, 0.0), dr.select(ok, -oz, 1.0))
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
        raise ValueError("Mitsuba has no variant set; call workbench.render.variants.select_variant() first")
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
        raise ValueError(f"weight={weight!r}: allowed 'irradiance' or 'radiance'")
    if not (math.isfinite(sensor_width_mm) and sensor_width_mm > 0):
        raise ValueError(f"sensor_width_mm={sensor_width_mm}: must be a finite number > 0")
    try:
        w_px, h_px = int(film_dict["width"]), int(film_dict["height"])
    except (KeyError, TypeError, ValueError):
        raise ValueError("film_dict: needs integer 'width' and 'height'") from None
    import drjit as dr
    import mitsuba as mi
    if str(mi.variant()).startswith("scalar"):
        raise ValueError(f"the Mitsuba lens camera needs a JIT variant (llvm_ad_spectral or cuda_ad_spectral), "
                         f"not {mi.variant()!r}")
    name = register_lens_sensor()
    dispersive = dispersion and _is_dispersive(lens)
    if dispersive:
        for s in lens.surfaces:
            _index_expr(s.material, mi.Float(LINE_D_NM), dr, mi)  # refuse tables early
    width_mm = float(sensor_width_mm)
    height_mm = width_mm * h_px / w_px
    max_r = 0.5 * math.hypot(width_mm, height_mm)
    edges, boxes = pupil_bins(lens, max_r, n_bins)
    zs, zr = sensor_z_mm(lens), lens.total_track_mm
    scale = 1.0
    if weight == "radiance":
        from workbench.optics.lens.analysis import irradiance_per_radiance
        e0 = irradiance_per_radiance(lens, 0.0)
        if e0 <= 0:
            raise ValueError(f"lens {lens.name!r}: no ray reaches the centre of the sensor")
        scale = 1.0 / e0
    key = f"lens{next(_counter)}"
    _LENSES[key] = {
        "lens": lens, "dispersive": dispersive, "width_mm": width_mm, "height_mm": height_mm,
        "max_radius_mm": float(edges[-1]), "n_bins": n_bins,
        "box_x0": mi.Float(boxes[:, 0]), "box_x1": mi.Float(boxes[:, 1]),
        "box_y0": mi.Float(boxes[:, 2]), "box_y1": mi.Float(boxes[:, 3]),
        "sensor_z_mm": float(zs), "rear_z_mm": float(zr), "scale": float(scale),
        "entrance_pupil_z_mm": float(paraxial(lens).entrance_pupil_mm),
    }
    out = {"type": name, "lens_key": key, "to_world": to_world, "film": film_dict}
    if sampler is not None:
        out["sampler"] = sampler
    return out

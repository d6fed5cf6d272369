"""The real lens inside Mitsuba 3: a Python `mi.Sensor` that traces every camera ray through the lens.

Algorithm (PBRT's realistic camera): the film sample gives a point on the sensor plane; the aperture
sample picks a point in the exit-pupil box of that point's radial bin (boxes precomputed in numpy
and cached per lens, focus and film size); the ray from the film point to that point is traced
backwards through every surface with Dr.Jit arithmetic (vertex-relative intersection, Snell, masks
for misses and TIR); its weight is cos⁴θ · A_box / z_rear² (0 for rays that die, which leave the
entrance pupil along the paraxial chief ray of their film point, so label and depth casts through
this sensor still see the right pixel). With `weight="irradiance"` the film then holds
E = ∫ L cos⁴θ / z² dA, the camera equation (π L /(4N²) on axis for a uniform scene); with
`weight="radiance"` it is divided by the on-axis value so a uniform scene reads L at the centre,
as with the perspective camera.

Cost (llvm, `workbench bench lens-camera`): spheres are hit without a division and need no
normalised normal, flat surfaces refract with n = (0, 0, 1), arithmetic is fused and every lens
constant is a Python float, so a camera ray costs about 2× a perspective one in an empty scene.

`full_model_camera` / `full_model_optical_image` make this camera the full optics model of a
project (render.city_frame.render_city_frame, bench optics): the lens prepared as optics.formation
prepares it, and the film read as sensor irradiance.

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
from dataclasses import dataclass

import numpy as np

from workbench.optics.lens.analysis import rear_pupil_box
from workbench.optics.lens.glass import LINE_D_NM, Material
from workbench.optics.lens.model import Lens
from workbench.optics.lens.paraxial import paraxial, sensor_z_mm

PLUGIN_NAME = "workbench_lens"
N_BINS = 32

_LENSES: dict[str, dict] = {}       # key → prepared lens data, looked up by the plugin
_KEYS: dict[tuple, str] = {}
_BOX_CACHE: dict[tuple, tuple] = {}
_counter = itertools.count()
_registered: set[str] = set()


ELLIPSE_MARGIN = 0.98   # a bin samples its box's inscribed ellipse when no light passes outside 0.98 of it


def _ellipse_holds_pupil(lens: Lens, heights_mm, box, wavelength_nm: float, n_side: int = 64) -> bool:
    """True when no ray from the film points at `heights_mm` (on +y) that passes the whole lens
    crosses the rear-vertex plane outside ELLIPSE_MARGIN × the ellipse inscribed in `box`
    (checked on an n_side² grid over the box), so sampling the ellipse loses no light."""
    from workbench.optics.lens.analysis import _rear_rays
    from workbench.optics.lens.trace import trace_rays
    x0, x1, y0, y1 = box
    g = (np.arange(n_side) + 0.5) / n_side * 2.0 - 1.0
    u, v = (a.ravel() for a in np.meshgrid(g, g))
    out = u * u + v * v > ELLIPSE_MARGIN ** 2
    xy = np.column_stack([(x0 + x1) / 2 + u[out] * (x1 - x0) / 2, (y0 + y1) / 2 + v[out] * (y1 - y0) / 2])
    for h in heights_mm:
        p, d, _ = _rear_rays(lens, float(h), xy)
        if trace_rays(lens, p, d, wavelength_nm, reverse=True).valid.any():
            return False
    return True


def pupil_bins(lens: Lens, max_radius_mm: float, n_bins: int = N_BINS,
               wavelength_nm: float = LINE_D_NM) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exit-pupil boxes per radial bin of the film: (edges (n+1,), boxes (n, 4) as x0, x1, y0, y1
    on the rear-vertex plane for film points on +y, an all-zero box where no ray passes; ellipse
    (n,) bool: the bin may sample the box's inscribed ellipse instead (π/4 of the area, so fewer
    rays die; checked at the bin's edges and centre). Cached."""
    key = (lens, round(max_radius_mm, 9), n_bins, wavelength_nm)
    if key in _BOX_CACHE:
        return _BOX_CACHE[key]
    edges = np.linspace(0.0, max_radius_mm * 1.0001, n_bins + 1)
    at = [rear_pupil_box(lens, float(h), wavelength_nm) for h in edges]
    boxes = np.zeros((n_bins, 4))
    ellipse = np.zeros(n_bins, dtype=bool)
    for i in range(n_bins):
        have = [b for b in (at[i], at[i + 1]) if b is not None]
        if have:
            boxes[i] = (min(b[0] for b in have), max(b[1] for b in have),
                        min(b[2] for b in have), max(b[3] for b in have))
            ellipse[i] = _ellipse_holds_pupil(lens, (edges[i], (edges[i] + edges[i + 1]) / 2, edges[i + 1]),
                                              boxes[i], wavelength_nm)
    _BOX_CACHE[key] = (edges, boxes, ellipse)
    return edges, boxes, ellipse


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


FAST_SPHERE_MIN_SAG = 1e-2   # |c|·a above which a sphere is hit by the division-free root


def _surface_constants(lens: Lens) -> list[dict]:
    """Per-surface constants of the reverse trace as Python floats (they become kernel literals)."""
    zv = lens.vertex_z_mm
    media = lens.media()
    out = []
    for i in reversed(range(len(lens.surfaces))):
        s = lens.surfaces[i]
        c = float(s.curvature_per_mm)
        sphere = c != 0.0 and s.conic == 0.0 and not s.is_aspheric
        out.append({"surface": s, "z": float(zv[i]), "c": c, "kk": 1.0 + float(s.conic),
                    "r2": float(s.semi_aperture_mm) ** 2, "after": media[i + 1], "before": media[i],
                    "sphere": sphere,
                    "fast": sphere and abs(c) * float(s.semi_aperture_mm) > FAST_SPHERE_MIN_SAG})
    return out


def _hit_sphere_fast(k, px, py, qz, dx, dy, dz, dr):
    """Hit of a unit-direction ray with a strongly curved sphere c|p|² − 2z = 0 (vertex-relative):
    t = (−b ± √(b² − cC))/c with PBRT's root rule (the root that meets the vertex cap of a ray
    travelling −z is (−b + √·)/c for either sign of c), no division. Its float32 error, about
    2⁻²⁴/|c|, stays below 6·10⁻⁶ of the clear aperture for |c|·a > FAST_SPHERE_MIN_SAG; flatter
    spheres take the stable two-root form. Returns (t, hit)."""
    c = k["c"]
    b = dr.fma(c, dr.fma(px, dx, dr.fma(py, dy, qz * dz)), -dz)
    C = dr.fma(c, dr.fma(px, px, dr.fma(py, py, qz * qz)), -2.0 * qz)
    disc = dr.fma(b, b, -c * C)
    sq = dr.sqrt(dr.maximum(disc, 0.0))
    t = (dr.select(dz < 0.0, sq, -sq) - b) * (1.0 / c)
    hit = (disc >= 0.0) & (t >= -1e-9) & (c * dr.fma(t, dz, qz) <= 1.0 + 1e-6)
    return t, hit


def _hit_general(k, px, py, qz, dx, dy, dz, dr):
    """Hit of a flat, conic, aspheric or nearly flat surface by the stable vertex-relative roots
    C/q and q/A: the nearest ahead on the vertex branch (Newton refinement for aspheres).
    Returns (t, hit)."""
    c, kk, s = k["c"], k["kk"], k["surface"]
    dz_ok = dr.abs(dz) > 1e-12
    t_plane = -qz / dr.select(dz_ok, dz, 1.0)
    if c == 0.0 and not s.is_aspheric:
        return t_plane, dz_ok & (t_plane >= -1e-9)
    if c == 0.0:
        t, hit = t_plane, dz_ok
    else:
        A = c * (dx * dx + dy * dy + kk * dz * dz)
        b = c * (px * dx + py * dy + kk * qz * dz) - dz
        C = c * (px * px + py * py + kk * qz * qz) - 2.0 * qz
        disc = b * b - A * C
        q = -(b + dr.copysign(dr.sqrt(dr.maximum(disc, 0.0)), b))
        t1 = C / dr.select(q != 0.0, q, 1.0)
        t2 = q / dr.select(A != 0.0, A, 1.0)
        ok1 = (q != 0.0) & (t1 >= -1e-9) & (kk * c * (qz + t1 * dz) <= 1.0 + 1e-9)
        ok2 = (A != 0.0) & (t2 >= -1e-9) & (kk * c * (qz + t2 * dz) <= 1.0 + 1e-9)
        t = dr.select(ok1 & (~ok2 | (t1 <= t2)), t1, t2)
        hit = (disc >= 0.0) & (ok1 | ok2)
    if s.is_aspheric:
        t, hit = _newton_asphere(s, px, py, qz, dx, dy, dz, dr.select(hit, t, t_plane), dr)
    return t, hit


def _trace_reverse(lens: Lens, px, py, pz, dx, dy, dz, wl, dr, mi):
    """Trace Dr.Jit rays (lens coordinates, unit directions travelling −z) from the sensor to object
    space at wavelength `wl` (a Dr.Jit Float, or None for the d-line indices as constants).
    Returns (px, py, pz, dx, dy, dz, valid).

    Per surface, only what it needs: strongly curved spheres the division-free hit
    (_hit_sphere_fast), other surfaces the stable one; spheres skip normalising their normal
    (−cx, −cy, 1 − cz), unit length on the surface; flat surfaces refract with n = (0, 0, 1); the
    stop only clips. Arithmetic is fused (dr.fma) and constants are Python floats."""
    valid = mi.Bool(True)
    for k in _surface_constants(lens):
        s, c, kk = k["surface"], k["c"], k["kk"]
        qz = pz - k["z"]
        t, hit = (_hit_sphere_fast if k["fast"] else _hit_general)(k, px, py, qz, dx, dy, dz, dr)
        px, py, qz = dr.fma(t, dx, px), dr.fma(t, dy, py), dr.fma(t, dz, qz)
        pz = qz + k["z"]
        valid &= hit & (dr.fma(px, px, py * py) <= k["r2"])
        if wl is None:
            n1, n2 = float(k["after"].nd), float(k["before"].nd)
        else:
            n1, n2 = _index_expr(k["after"], wl, dr, mi), _index_expr(k["before"], wl, dr, mi)
        if s.is_stop or (isinstance(n1, float) and isinstance(n2, float) and n1 == n2):
            continue
        mu = n1 / n2
        mu2 = mu * mu
        if c == 0.0 and not s.is_aspheric:          # flat: normal (0, 0, 1)
            kt = dr.fma(mu2, dz * dz, 1.0 - mu2)
            valid &= kt >= 0.0
            coef = dr.fma(-mu, dz, dr.copysign(dr.sqrt(dr.maximum(kt, 0.0)), dz))
            dx, dy, dz = mu * dx, mu * dy, dr.fma(mu, dz, coef)
            continue
        if s.is_aspheric:
            _, ds = _sag_dr(s, px * px + py * py, dr)
            nx, ny, nz = -2.0 * px * ds, -2.0 * py * ds, mi.Float(1.0)
        else:
            nx, ny, nz = -c * px, -c * py, dr.fma(-c * kk, qz, 1.0)
        if not k["sphere"]:
            inv = dr.rsqrt(nx * nx + ny * ny + nz * nz)
            nx, ny, nz = nx * inv, ny * inv, nz * inv
        cosi = dr.fma(dx, nx, dr.fma(dy, ny, dz * nz))
        # d' = μd + (±√k − μ cosi) n with the root's sign that of cosi: unit length, either normal sense.
        kt = dr.fma(mu2, cosi * cosi, 1.0 - mu2)
        valid &= kt >= 0.0
        coef = dr.fma(-mu, cosi, dr.copysign(dr.sqrt(dr.maximum(kt, 0.0)), cosi))
        dx, dy, dz = dr.fma(mu, dx, coef * nx), dr.fma(mu, dy, coef * ny), dr.fma(mu, dz, coef * nz)
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
            px, py, pz, ox, oy, oz, ok = _trace_reverse(lens, fx, fy, mi.Float(zs), dx, dy, dz, wl, dr, mi)
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
    edges, boxes, ellipse = pupil_bins(lens, max_r, n_bins)
    half_x, half_y = (boxes[:, 1] - boxes[:, 0]) / 2, (boxes[:, 3] - boxes[:, 2]) / 2
    zs, zr = sensor_z_mm(lens), lens.total_track_mm
    scale = 1.0
    if weight == "radiance":
        from workbench.optics.lens.analysis import irradiance_per_radiance
        e0 = irradiance_per_radiance(lens, 0.0)
        if e0 <= 0:
            raise ValueError(f"lens {lens.name!r}: no ray reaches the centre of the sensor")
        scale = 1.0 / e0
    pdata = paraxial(lens)
    ident = (lens, width_mm, height_mm, n_bins, dispersive, float(scale))
    key = _KEYS.setdefault(ident, f"lens{next(_counter)}")   # the same camera reuses its entry
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


def full_model_camera(params, camera) -> FullModelCamera:
    """The full model's camera for OpticsParams `params` (lens_file required) on the project's
    camera geometry `camera` (optics.formation.geometry.CameraGeometry): the lens prepared as
    formation/ prepares it (scale_lens_to_focal_length, stop resized to f_number), focused on
    camera.focus_distance_m; the sensor is camera.sensor_width_m wide at camera.image_distance_m."""
    from workbench.optics.formation import lens_setup
    lens, _ = lens_setup.focused_lens(params, camera.focus_distance_m)
    return FullModelCamera(lens, float(camera.sensor_width_m * 1e3), float(camera.image_distance_m),
                           float(camera.focal_length_m), float(paraxial(lens).f_number),
                           float(camera.focus_distance_m))


def full_model_optical_image(irradiance_photons: np.ndarray, wavelengths_nm: np.ndarray,
                             camera: FullModelCamera, params, *, depth_m=None, meta: dict | None = None):
    """The OpticalImage of a render through lens_sensor_dict(camera.lens, …, weight='irradiance'):
    the film already holds sensor irradiance (photons/s/m²/nm, upright, on square samples of
    sensor_width_mm / columns); this applies the transmittance and, with
    params.raytrace_diffraction, the Airy pattern of the working f-number integrated over each
    sample (as the raytrace level does: geometric blur ⊛ Airy)."""
    from workbench.errors import check_finite
    from workbench.optics.formation import diffraction, fourier
    from workbench.optics.types import OpticalImage
    irr = np.asarray(irradiance_photons, dtype=np.float64) * params.transmittance
    if irr.ndim != 3 or irr.shape[2] != np.size(wavelengths_nm):
        raise ValueError(f"irradiance_photons must be H×W×Nλ with Nλ = {np.size(wavelengths_nm)}, got {irr.shape}")
    dx = camera.sensor_width_mm * 1e-3 / irr.shape[1]
    clipped = 0.0
    if params.raytrace_diffraction:
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

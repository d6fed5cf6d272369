"""A row of identical luminaires as one mesh of glowing lens rectangles with one light sampler of
constant cost (a tunnel's lighting).

Each luminaire is a horizontal rectangle facing down, a Lambertian emitter of radiance L(λ)
(W/sr/m²/nm): on-axis intensity I₀ = L·A, luminous flux Φ = π·L_v·A. The camera sees the
lenses glow. The lenses are equally spaced along a line parallel to the y axis, all at one
height: centre k at (x_c, y₀ + k·s, z_c), k = 0 … N−1, each 2h_x across and 2h_y ≤ s along the
row. All of them are one mesh with one `luminaire_row` emitter, which Mitsuba picks with the
row's `sampling_weight`; the emitter then samples the row as a whole, in O(1) whatever N:

- along the row, t = y − y₀ over the row's cells [−s/2, (N − ½)s], the density
  f(t) = d² / (r³ · (sin φ₁ − sin φ₀)), r = √(d² + (t − t_p)²), d the distance of the shading
  point p from the line of lens centres, t_p its position along it, φ the angle of t seen from p
  (tan φ = (t − t_p)/d) and φ₀, φ₁ those of the row's ends: uniform in sin φ, so sampled by
  inverting sin φ = sin φ₀ + u·(sin φ₁ − sin φ₀), t = t_p + d·tan φ. The cell k = round(t/s)
  holding t is the lens, chosen with the integral of f over its cell;
- the cell is mapped onto its lens, y = y₀ + k·s + (t − k·s)·2h_y/s, so within a lens the
  density still follows 1/r³ (a near lens is not sampled uniformly), and across it x is uniform.

Why 1/r³: a lens element sends a point p the light L·cos θ_e·cos θ_p·dA/r², and cos θ_e/r² =
Δz/r³ along the row whatever p's orientation, so the sample weight (light / density) is bounded
by |cos θ_p| ≤ 1 for a road, a wall or a car's back alike. A 1/r² (Cauchy) density leaves a factor
cos φ in the weight: it samples the far lenses too often (relative variance of the row's part of
the road illuminance under an infinite row 0.5 against 0.08 with 1/r³); a 1/r⁴ density would
match the road alone but has no closed-form inverse and leaves receivers facing along the row an
unbounded weight.

The area density on the lens, f(t)·s/(2h_y)/(2h_x), is turned into solid angle at p (× r²/cos θ_e)
by pdf_direction, which evaluates it in O(1) for any lens point (k from the point's y), so that
sampling and pdf agree for MIS, also when a BSDF-sampled ray hits a lens. Every lens point has a
positive density from any point below the row, so the estimate is unbiased. Points at or above the
lenses' height get no light (the lenses face down).
"""
from __future__ import annotations

import numpy as np

from workbench.errors import InvalidValueError

_CLASSES: dict[str, type] = {}    # the emitter class per Mitsuba variant
PLUGIN = "luminaire_row"
ROW_TOLERANCE_M = 1e-4             # how far lens centres may stray from the equally spaced line


def row_emitter_class() -> type:
    """The `luminaire_row` emitter class of the current Mitsuba variant, registered as a plugin
    (once per variant)."""
    import drjit as dr
    import mitsuba as mi

    if mi.variant() in _CLASSES:
        return _CLASSES[mi.variant()]

    class LuminaireRow(mi.Emitter):
        """All lenses of a row: emits `radiance` downward, samples the row in O(1) (module docstring)."""

        def __init__(self, props):
            mi.Emitter.__init__(self, props)
            self.m_flags = mi.EmitterFlags.Surface
            self.radiance = props["radiance"]
            self.x, self.y0, self.z = (float(props[k]) for k in ("x_m", "y0_m", "z_m"))
            self.spacing, self.n = float(props["spacing_m"]), int(props["count"])
            self.hx, self.hy = float(props["half_x_m"]), float(props["half_y_m"])

        def _row(self, p):
            """(d, t_p, sin φ₀, sin φ₁ − sin φ₀, ok) of the shading point p (module docstring)."""
            dz = self.z - p.z
            d2 = dr.maximum(dr.square(self.x - p.x) + dr.square(dz), 1e-12)     # > 0 on the line itself
            tp = p.y - self.y0
            lo = -0.5 * self.spacing - tp
            hi = (self.n - 0.5) * self.spacing - tp
            s0 = lo * dr.rsqrt(d2 + dr.square(lo))
            s1 = hi * dr.rsqrt(d2 + dr.square(hi))
            return dr.sqrt(d2), tp, s0, s1 - s0, (dz > 0) & (s1 > s0)

        def _pdf(self, p, q, active):
            """Solid-angle density at p of the lens point q (module docstring), and where it is > 0."""
            d, tp, _, span, ok = self._row(p)
            rel = q.y - self.y0
            k = dr.clip(dr.round(rel / self.spacing), 0, self.n - 1)
            t = k * self.spacing + (rel - k * self.spacing) * (0.5 * self.spacing / self.hy)
            r2 = dr.square(d) + dr.square(t - tp)
            f = dr.square(d) * dr.rsqrt(r2) / (r2 * span)
            area_pdf = f * (0.5 * self.spacing / self.hy) / (2.0 * self.hx)
            v = q - p
            dist2 = dr.squared_norm(v)
            cos_e = v.z * dr.rsqrt(dist2)
            ok &= active & (cos_e > 0) & (area_pdf > 0)
            return dr.select(ok, area_pdf * dist2 / cos_e, 0.0), ok

        def _emitted(self, wavelengths, active):
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.wavelengths = wavelengths
            return self.radiance.eval(si, active)

        def sample_direction(self, it, sample, active=True):
            d, tp, s0, span, _ = self._row(it.p)
            sin_phi = s0 + dr.clip(sample.x, 0.0, 1.0) * span
            t = tp + d * sin_phi * dr.rsqrt(dr.maximum((1.0 - sin_phi) * (1.0 + sin_phi), 1e-30))
            k = dr.clip(dr.round(t / self.spacing), 0, self.n - 1)
            along = dr.clip((t - k * self.spacing) * (2.0 * self.hy / self.spacing), -self.hy, self.hy)
            q = mi.Point3f(self.x + (2.0 * sample.y - 1.0) * self.hx, self.y0 + k * self.spacing + along, self.z)
            pdf, ok = self._pdf(it.p, q, active)
            v = q - it.p
            dist = dr.norm(v)
            ds = dr.zeros(mi.DirectionSample3f)
            ds.p, ds.n, ds.d, ds.dist = q, mi.Normal3f(0.0, 0.0, -1.0), v / dist, dist
            ds.pdf, ds.delta, ds.time = pdf, False, it.time
            ds.emitter = mi.EmitterPtr(self)
            value = self._emitted(it.wavelengths, ok) / dr.select(ok, pdf, 1.0)
            return ds, dr.select(ok, value, 0.0)

        def pdf_direction(self, it, ds, active=True):
            return self._pdf(it.p, ds.p, active)[0]

        def eval_direction(self, it, ds, active=True):
            ok = active & (ds.d.z > 0)
            return dr.select(ok, self._emitted(it.wavelengths, ok), 0.0)

        def eval(self, si, active=True):
            ok = active & (mi.Frame3f.cos_theta(si.wi) > 0)
            return dr.select(ok, self._emitted(si.wavelengths, ok), 0.0)

        def traverse(self, callback):
            pass

        def to_string(self):
            return f"LuminaireRow[{self.n} lenses every {self.spacing} m]"

    mi.register_emitter(PLUGIN, lambda props: LuminaireRow(props))
    _CLASSES[mi.variant()] = LuminaireRow
    return LuminaireRow


def row_layout(centres_m: np.ndarray, half_size_m: tuple[float, float]) -> dict[str, float]:
    """The row's parameters (x_m, y0_m, z_m, spacing_m, count, half_x_m, half_y_m) from its lens
    centres (N×3, m, any order) and half sizes (x, y) m; InvalidValueError unless the centres are
    equally spaced on a line parallel to the y axis at one height, ≥ 2h_y apart (lenses that do
    not overlap)."""
    pts = np.atleast_2d(np.asarray(centres_m, dtype=np.float64))
    hx, hy = (float(h) for h in half_size_m)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0 or not np.all(np.isfinite(pts)):
        raise InvalidValueError(f"lens centres must be N×3 finite (N ≥ 1), got shape {pts.shape}")
    if not (hx > 0 and hy > 0):
        raise InvalidValueError(f"lens half sizes must be > 0, got {half_size_m}")
    pts = pts[np.argsort(pts[:, 1])]
    n = len(pts)
    spacing = float((pts[-1, 1] - pts[0, 1]) / (n - 1)) if n > 1 else 2 * hy
    line = np.column_stack([np.full(n, pts[0, 0]), pts[0, 1] + spacing * np.arange(n), np.full(n, pts[0, 2])])
    if np.abs(pts - line).max() > ROW_TOLERANCE_M or spacing < 2 * hy * (1 - 1e-9):
        raise InvalidValueError(f"lens centres must be equally spaced along y at one x and one height, at least "
                                f"the lens length {2 * hy} m apart (a luminaire row); got {n} centres from "
                                f"{pts[0].tolist()} to {pts[-1].tolist()}")
    return {"x_m": float(pts[0, 0]), "y0_m": float(pts[0, 1]), "z_m": float(pts[0, 2]), "spacing_m": spacing,
            "count": n, "half_x_m": hx, "half_y_m": hy}


def luminaire_row_shape(name: str, centres_m: np.ndarray, half_size_m: tuple[float, float],
                        radiance_spectrum: dict, sampling_weight: float, exterior=None, plugin: str = PLUGIN,
                        extra: dict | None = None):
    """One Mitsuba mesh `name` of the lenses (a spectral variant must be set): horizontal
    rectangles facing down at centres_m (N×3, m; row_layout), half sizes (x, y) m, black, with
    one `luminaire_row` emitter of `radiance_spectrum` (a Mitsuba spectrum dict, W/sr/m²/nm)
    weighing `sampling_weight` in Mitsuba's light selection; `exterior` an optional loaded medium.
    plugin, extra: a registered subclass of the row's emitter and its further properties (the row
    that carries the sun: render/tunnel_sun_share.py)."""
    import mitsuba as mi

    if not sampling_weight > 0:
        raise InvalidValueError(f"sampling_weight must be > 0, got {sampling_weight}")
    row = row_layout(centres_m, half_size_m)
    row_emitter_class()
    props = mi.Properties()
    props["emitter"] = mi.load_dict({"type": plugin, "sampling_weight": float(sampling_weight),
                                     "radiance": mi.load_dict(radiance_spectrum), **row, **(extra or {})})
    if exterior is not None:
        props["exterior"] = exterior
    n, hx, hy = row["count"], row["half_x_m"], row["half_y_m"]
    y = row["y0_m"] + row["spacing_m"] * np.arange(n)
    corners = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    v = np.zeros((n, 4, 3))
    v[..., 0] = row["x_m"] + corners[:, 0]
    v[..., 1] = y[:, None] + corners[:, 1]
    v[..., 2] = row["z_m"]
    base = 4 * np.arange(n)[:, None]
    faces = np.concatenate([base + [0, 2, 1], base + [0, 3, 2]])    # clockwise from above: normals −z
    mesh = mi.Mesh(name, 4 * n, 2 * n, props, has_vertex_normals=False, has_vertex_texcoords=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = type(params["vertex_positions"])(v.astype(np.float32).ravel())
    params["faces"] = type(params["faces"])(faces.astype(np.uint32).ravel())
    params.update()
    mesh.set_bsdf(mi.load_dict({"type": "diffuse", "reflectance": {"type": "spectrum", "value": 0.0}}))
    return mesh

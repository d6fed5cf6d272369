"""A row of identical luminaires as glowing lens rectangles that share one light sampler (a
tunnel's lighting).

Each luminaire is a horizontal rectangle facing down, a Lambertian emitter of radiance L(λ)
(W/sr/m²/nm): on-axis intensity I₀ = L·A, luminous flux Φ = π·L_v·A. The camera sees the
lenses glow. Sampled one by one, Mitsuba would pick a lens at random for each next-event
sample, and a road point lit mostly by its 2–3 nearest luminaires would find the right one once
in N/3 samples. So every lens carries the same `luminaire_row` emitter, which samples the whole
row: lens k with probability p_k ∝ 1/r_k² among the lenses above the shading point (r_k to its
centre), then a point uniformly on it. With N lens emitters picked alike, the density of a
direction ω toward lens k is N·P·p_row(ω), P the selection probability of one lens emitter and
p_row(ω) = p_k / A · r² / cos θ_e; each emitter reports N·p_row as its pdf (for MIS with BSDF
sampling, also when a ray hits a lens) and the sample's value divided by it, so the estimate is
that of the whole row, unbiased.
"""
from __future__ import annotations

import hashlib

import numpy as np

from workbench.errors import InvalidValueError

_ROWS: dict[str, tuple] = {}       # row key → (centres N×3, half x, half y, radiance texture)
MAX_ROWS = 64                      # newest rows kept; a row is read only while its scene is loaded
_REGISTERED: set[str] = set()
PLUGIN = "luminaire_row"


def _register() -> None:
    """Register the `luminaire_row` emitter plugin for the current Mitsuba variant (once)."""
    import drjit as dr
    import mitsuba as mi

    if mi.variant() in _REGISTERED:
        return

    class LuminaireRow(mi.Emitter):
        """One lens of a row: emits `radiance` downward, samples the whole row (module docstring)."""

        def __init__(self, props):
            mi.Emitter.__init__(self, props)
            self.m_flags = mi.EmitterFlags.Surface
            centres, self.hx, self.hy, self.radiance = _ROWS[props["row"]]
            self.centres = [tuple(float(c) for c in p) for p in centres]
            self.lens = int(props["lens"])         # which lens it is (also keeps the lenses' dicts distinct)

        def _weights(self, p):
            out = []
            for x, y, z in self.centres:
                d = mi.Vector3f(x, y, z) - p
                out.append(dr.select(d.z > 0, dr.rcp(dr.squared_norm(d)), 0.0))
            total = out[0]
            for w in out[1:]:
                total = total + w
            return out, total

        def _pdf(self, p, q, w_k, total):
            """N · p_row of the direction from p to the lens point q (of a lens with weight w_k)."""
            d = q - p
            dist2 = dr.squared_norm(d)
            cos_e = d.z * dr.rsqrt(dist2)
            area = 4.0 * self.hx * self.hy
            ok = (total > 0) & (w_k > 0) & (cos_e > 0)
            return dr.select(ok, len(self.centres) * w_k / total / area * dist2 / cos_e, 0.0), ok

        def _emitted(self, wavelengths, active):
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.wavelengths = wavelengths
            return self.radiance.eval(si, active)

        def sample_direction(self, it, sample, active=True):
            w, total = self._weights(it.p)
            u = sample.x * total
            cum = mi.Float(0.0)
            centre, w_k, u_k = mi.Point3f(*self.centres[-1]), w[-1], mi.Float(0.5)
            done = mi.Bool(False)
            for c, wk in zip(self.centres, w):
                take = ~done & (u < cum + wk) & (wk > 0)
                centre = dr.select(take, mi.Point3f(*c), centre)
                u_k = dr.select(take, (u - cum) / wk, u_k)
                w_k = dr.select(take, wk, w_k)
                done = done | take
                cum = cum + wk
            q = centre + mi.Vector3f((2 * dr.clip(u_k, 0.0, 1.0) - 1) * self.hx, (2 * sample.y - 1) * self.hy, 0.0)
            pdf, ok = self._pdf(it.p, q, w_k, total)
            ok &= active
            d = q - it.p
            dist = dr.norm(d)
            ds = dr.zeros(mi.DirectionSample3f)
            ds.p, ds.n, ds.d, ds.dist = q, mi.Normal3f(0.0, 0.0, -1.0), d / dist, dist
            ds.pdf, ds.delta, ds.time = dr.select(ok, pdf, 0.0), False, it.time
            ds.emitter = mi.EmitterPtr(self)
            value = self._emitted(it.wavelengths, ok) / dr.select(ok, pdf, 1.0)
            return ds, dr.select(ok, value, 0.0)

        def pdf_direction(self, it, ds, active=True):
            w, total = self._weights(it.p)
            w_k = mi.Float(0.0)
            for (x, y, z), wk in zip(self.centres, w):
                inside = (dr.abs(ds.p.x - x) <= self.hx * 1.001) & (dr.abs(ds.p.y - y) <= self.hy * 1.001) & \
                    (dr.abs(ds.p.z - z) < 1e-3)
                w_k = dr.select(inside, wk, w_k)
            pdf, ok = self._pdf(it.p, ds.p, w_k, total)
            return dr.select(active & ok, pdf, 0.0)

        def eval_direction(self, it, ds, active=True):
            ok = active & (ds.d.z > 0)
            return dr.select(ok, self._emitted(it.wavelengths, ok), 0.0)

        def eval(self, si, active=True):
            ok = active & (mi.Frame3f.cos_theta(si.wi) > 0)
            return dr.select(ok, self._emitted(si.wavelengths, ok), 0.0)

        def traverse(self, callback):
            pass

        def to_string(self):
            return f"LuminaireRow[{len(self.centres)} lenses]"

    mi.register_emitter(PLUGIN, lambda props: LuminaireRow(props))
    _REGISTERED.add(mi.variant())


def luminaire_row_shapes(centres_m: np.ndarray, half_size_m: tuple[float, float], radiance_spectrum: dict,
                         sampling_weight: float) -> list[dict]:
    """Mitsuba shape dicts of the lenses (a spectral variant must be set): horizontal rectangles
    facing down at centres_m (N×3, m), half sizes (x, y) m, each a `luminaire_row` emitter of
    `radiance_spectrum` (a Mitsuba spectrum dict, W/sr/m²/nm); together they weigh
    `sampling_weight` in Mitsuba's light selection."""
    import mitsuba as mi

    pts = np.atleast_2d(np.asarray(centres_m, dtype=np.float64))
    hx, hy = (float(h) for h in half_size_m)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0 or not np.all(np.isfinite(pts)):
        raise InvalidValueError(f"lens centres must be N×3 finite (N ≥ 1), got shape {pts.shape}")
    if not (hx > 0 and hy > 0 and sampling_weight > 0):
        raise InvalidValueError(f"half sizes and sampling_weight must be > 0, got {half_size_m}, {sampling_weight}")
    key = hashlib.sha1(np.r_[pts.ravel(), hx, hy].tobytes() + repr(radiance_spectrum).encode()).hexdigest()
    _ROWS.pop(key, None)
    _ROWS[key] = (pts, hx, hy, mi.load_dict(radiance_spectrum))
    while len(_ROWS) > MAX_ROWS:                    # the oldest first: a long data set stays small
        _ROWS.pop(next(iter(_ROWS)))
    _register()
    emitter = {"type": PLUGIN, "row": key, "sampling_weight": float(sampling_weight) / len(pts)}
    black = {"type": "diffuse", "reflectance": {"type": "spectrum", "value": 0.0}}
    return [{"type": "rectangle", "emitter": {**emitter, "lens": k}, "bsdf": dict(black),
             "to_world": mi.ScalarTransform4f().translate(p.tolist()).rotate([1, 0, 0], 180).scale([hx, hy, 1.0])}
            for k, p in enumerate(pts)]

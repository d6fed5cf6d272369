"""A row of identical full cut-off point luminaires as ONE Mitsuba emitter (a tunnel's lighting).

Each luminaire radiates the same intensity I(λ) (W/sr/nm) into the whole lower hemisphere and
nothing upward, like lamps.street_lamp_emitter. As separate emitters, Mitsuba would pick one of
the N at random for each next-event sample, and a road point lit mostly by its 2–3 nearest
luminaires would see the right one once in N/3 samples. Here the row picks luminaire k with
probability p_k ∝ 1/r_k² among those above the shading point (r_k its distance), so the sample's
value I/(r_k² p_k) = I Σ_j 1/r_j² no longer depends on which one was picked: only visibility and
the receiver's cosine stay noisy. Unbiased: E[I/(r² p)] over the choice = Σ_k I/r_k².
"""
from __future__ import annotations

import numpy as np

_REGISTERED: dict[str, type] = {}


def _emitter_class():
    """The LuminaireRow class of the current Mitsuba variant (Python plugins are per variant)."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant in _REGISTERED:
        return _REGISTERED[variant]

    class LuminaireRow(mi.Emitter):
        """N point luminaires (positions (x, y, z) m), intensity texture I(λ) over the lower
        hemisphere of each; luminaire choice ∝ 1/r² (module docstring)."""

        def __init__(self, props, points=(), intensity=None):
            mi.Emitter.__init__(self, props)
            self.m_flags = mi.EmitterFlags.DeltaPosition
            self.points = [tuple(float(c) for c in p) for p in points]
            self.intensity = intensity

        def _weights(self, p):
            """1/r² of every luminaire above p (0 for those level with or below it)."""
            out = []
            for x, y, z in self.points:
                d = mi.Vector3f(x, y, z) - p
                out.append(dr.select(d.z > 0, dr.rcp(dr.squared_norm(d)), 0.0))
            return out

        def sample_direction(self, it, sample, active=True):
            w = self._weights(it.p)
            total = w[0]
            for wk in w[1:]:
                total = total + wk
            u = sample.x * total
            chosen = mi.Point3f(*self.points[-1])
            w_chosen = w[-1]
            done = mi.Bool(False)
            cum = mi.Float(0.0)
            for (x, y, z), wk in zip(self.points, w):
                cum = cum + wk
                take = ~done & (u < cum) & (wk > 0)
                chosen = dr.select(take, mi.Point3f(x, y, z), chosen)
                w_chosen = dr.select(take, wk, w_chosen)
                done = done | take
            ok = active & (total > 0) & (w_chosen > 0)
            d = chosen - it.p
            dist = dr.norm(d)
            ds = dr.zeros(mi.DirectionSample3f)
            ds.p, ds.d, ds.dist, ds.n = chosen, d / dist, dist, mi.Normal3f(0.0, 0.0, 0.0)
            ds.pdf = dr.select(ok, w_chosen / total, 0.0)
            ds.delta, ds.time, ds.emitter = True, it.time, mi.EmitterPtr(self)
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.wavelengths = it.wavelengths
            value = self.intensity.eval(si, ok) * total          # I/(r² p) = I Σ 1/r_j²
            return ds, dr.select(ok, value, 0.0)

        def pdf_direction(self, it, ds, active=True):
            return mi.Float(0.0)

        def eval_direction(self, it, ds, active=True):
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.wavelengths = it.wavelengths
            below = active & (ds.d.z < 0)
            return dr.select(below, self.intensity.eval(si, below) * dr.rcp(dr.square(ds.dist)), 0.0)

        def eval(self, si, active=True):
            return mi.Spectrum(0.0)

        def traverse(self, callback):
            pass

        def to_string(self):
            return f"LuminaireRow[{len(self.points)} luminaires]"

    _REGISTERED[variant] = LuminaireRow
    return LuminaireRow


def luminaire_row_emitter(points_m: np.ndarray, intensity_spectrum: dict, sampling_weight: float):
    """A LuminaireRow emitter object (a spectral variant must be set): luminaires at points_m
    (N×3, m), each of radiant intensity `intensity_spectrum` (a Mitsuba spectrum dict, W/sr/nm)
    into its lower hemisphere; `sampling_weight` is its share in Mitsuba's light selection."""
    import mitsuba as mi

    pts = np.atleast_2d(np.asarray(points_m, dtype=np.float64))
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0 or not np.all(np.isfinite(pts)):
        raise ValueError(f"luminaire points must be N×3 finite (N ≥ 1), got shape {pts.shape}")
    if not sampling_weight > 0:
        raise ValueError(f"sampling_weight must be > 0, got {sampling_weight}")
    props = mi.Properties()
    props["sampling_weight"] = float(sampling_weight)
    return _emitter_class()(props, pts.tolist(), mi.load_dict(intensity_spectrum))

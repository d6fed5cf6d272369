"""Many spot lamps as one Mitsuba emitter that picks, for each next-event sample, a lamp by its
light at the shading point (NightParams.light_selection 'shading').

Mitsuba 3 picks the emitter for next-event estimation (NEE) from one global table
(`sampling_weight`), the same at every point. In a city at night a point lit almost only by the
lamp 3 m away then finds that lamp once in tens of samples, and the rare sample that does find it
is weighted by 1/p, so the point is a firefly: at night the fireflies are the one-bounce indirect
light (render.max_depth 2 has none) of surfaces lit by a lamp whose global share is small. This
emitter holds all the lamps (`spot_emitter` dicts) and samples lamp k with probability

    p_k(x) = w_k(x) / Σ_j w_j(x),   w_k(x) = I_k · g_k(x) · (|cos θ_x| + COS_FLOOR) / r_k²,

I_k the lamp's peak intensity (cd), g_k a cone factor (1 inside the beam, falling linearly in
cos θ to 0 at the cut-off: zero exactly where the lamp sheds no light), r_k the distance and θ_x
the angle at the receiver (the floor keeps a lamp in the tangent plane or behind a pane
possible): a lamp's share follows its unshadowed direct light at x, as a light tree does in
PBRT-v4, without the tree (a linear scan: the city has tens of lamps). The value returned is the
Mitsuba `spot` emitter's own (intensity × the spot's angular falloff / r²) divided by p_k, so the
expected image is that of the separate spots; only the noise changes. Occlusion is not known to
the weights (a lamp behind a wall keeps its share). Lamps are point sources (delta position):
BSDF sampling never hits them, so no MIS weight is needed.
"""
from __future__ import annotations

import hashlib

import numpy as np

from workbench.errors import InvalidValueError

PLUGIN = "lamp_set"
COS_FLOOR = 0.05
_SETS: dict[str, dict] = {}        # set key → lamp arrays and spectra (read while its scene loads)
MAX_SETS = 64
_REGISTERED: set[str] = set()


def _spot_arrays(spots: dict) -> dict:
    """Per-lamp arrays from spot_emitter dicts: position (m), axis, cone (cosines; cut-off in rad,
    1/(cut-off − beam) in 1/rad), peak intensity (cd), and the distinct spectral shapes with each
    lamp's index into them and scale (W/sr/nm at the shape's maximum)."""
    pos, axis, cos_cut, cos_beam, cut, inv_tw, peak, kind, scale = ([] for _ in range(9))
    shapes: dict[bytes, int] = {}
    spectra = []
    for name, e in spots.items():
        if e.get("type") != "spot":
            raise InvalidValueError(f"lamp set: emitter '{name}' is a {e.get('type')!r}, only 'spot' lamps can join")
        m = np.array(e["to_world"].matrix, dtype=np.float64)
        a = m[:3, 2] / np.linalg.norm(m[:3, 2])
        c_deg, b_deg = float(e["cutoff_angle"]), float(e["beam_width"])
        wl, v = (np.array(x, dtype=np.float64) for x in zip(*e["intensity"]["value"]))
        s = float(v.max())
        if not s > 0:
            raise InvalidValueError(f"lamp set: emitter '{name}' has no positive intensity")
        key = hashlib.sha1(np.r_[wl, np.round(v / s, 12)].tobytes()).digest()
        if key not in shapes:
            shapes[key] = len(spectra)
            spectra.append({"type": "spectrum", "value": list(zip(wl.tolist(), (v / s).tolist()))})
        pos.append(m[:3, 3])
        axis.append(a)
        cos_cut.append(np.cos(np.radians(c_deg)))
        cos_beam.append(np.cos(np.radians(b_deg)))
        cut.append(np.radians(c_deg))
        inv_tw.append(1.0 / np.radians(c_deg - b_deg))
        # cd: spot_emitter's sampling_weight over its cone's solid angle 2π(1 − cos), as lamps.cone_solid_angle_sr
        # (not imported: lamps imports this module)
        peak.append(float(e["sampling_weight"]) / (2 * np.pi * (1 - np.cos(np.radians(c_deg)))))
        kind.append(shapes[key])
        scale.append(s)
    return {"pos": np.array(pos), "axis": np.array(axis), "cos_cut": np.array(cos_cut),
            "cos_beam": np.array(cos_beam), "cut": np.array(cut), "inv_tw": np.array(inv_tw),
            "peak": np.array(peak), "kind": np.array(kind), "scale": np.array(scale), "spectra": spectra}


def _register() -> None:
    """Register the `lamp_set` emitter plugin for the current Mitsuba variant (once)."""
    import drjit as dr
    import mitsuba as mi

    if mi.variant() in _REGISTERED:
        return

    class LampSet(mi.Emitter):
        """A set of spot lamps sampled by their light at the shading point (module docstring)."""

        def __init__(self, props):
            mi.Emitter.__init__(self, props)
            self.m_flags = mi.EmitterFlags.DeltaPosition
            s = _SETS[props["set"]]
            self.lamps = [tuple(float(x) for x in row) for row in np.c_[
                s["pos"], s["axis"], s["cos_cut"], s["cos_beam"], s["cut"], s["inv_tw"], s["peak"], s["scale"]]]
            self.kind = [int(k) for k in s["kind"]]
            self.spectra = [mi.load_dict(d) for d in s["spectra"]]

        def _weights(self, it):
            out = []
            for px, py, pz, ax, ay, az, cc, cb, _, _, peak, _ in self.lamps:
                d = mi.Vector3f(px, py, pz) - it.p
                r2 = dr.maximum(dr.squared_norm(d), 1e-8)
                u = d * dr.rsqrt(r2)
                cos_l = -(u.x * ax + u.y * ay + u.z * az)
                cone = dr.clip((cos_l - cc) / (cb - cc), 0.0, 1.0)
                out.append(peak * cone * (dr.abs(dr.dot(it.n, u)) + COS_FLOOR) / r2)
            total = out[0]
            for w in out[1:]:
                total = total + w
            return out, total

        def sample_direction(self, it, sample, active=True):
            w, total = self._weights(it)
            u = sample.x * total
            cum = mi.Float(0.0)
            done = mi.Bool(False)
            lamp = [mi.Float(v) for v in self.lamps[-1]]
            kind, w_k = mi.UInt32(self.kind[-1]), w[-1]
            for row, k, wk in zip(self.lamps, self.kind, w):
                take = ~done & (u < cum + wk) & (wk > 0)
                lamp = [dr.select(take, v, old) for v, old in zip(row, lamp)]
                kind = dr.select(take, k, kind)
                w_k = dr.select(take, wk, w_k)
                done = done | take
                cum = cum + wk
            px, py, pz, ax, ay, az, cc, cb, cut, inv_tw, _, scale = lamp
            ok = active & (total > 0) & (w_k > 0)
            p = mi.Point3f(px, py, pz)
            d = p - it.p
            dist = dr.norm(d)
            ds = dr.zeros(mi.DirectionSample3f)
            ds.p, ds.d, ds.dist, ds.n = p, d / dist, dist, mi.Normal3f(0.0)
            pdf = dr.select(ok, w_k / total, 0.0)
            ds.pdf, ds.delta, ds.time = pdf, True, it.time
            ds.emitter = mi.EmitterPtr(self)
            cos_t = -(ds.d.x * ax + ds.d.y * ay + ds.d.z * az)
            falloff = dr.select(cos_t >= cb, 1.0, (cut - dr.acos(dr.clip(cos_t, -1.0, 1.0))) * inv_tw)
            falloff = dr.select(cos_t > cc, falloff, 0.0)
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.wavelengths = it.wavelengths
            spec = self.spectra[0].eval(si, ok)
            for j, tex in enumerate(self.spectra[1:], start=1):
                spec = dr.select(kind == j, tex.eval(si, ok), spec)
            value = spec * (scale * falloff / (dist * dist) / dr.select(ok, pdf, 1.0))
            return ds, dr.select(ok, value, 0.0)

        def pdf_direction(self, it, ds, active=True):
            return mi.Float(0.0)

        def eval_direction(self, it, ds, active=True):
            return dr.zeros(mi.Spectrum)

        def eval(self, si, active=True):
            return dr.zeros(mi.Spectrum)

        def traverse(self, callback):
            pass

        def to_string(self):
            return f"LampSet[{len(self.lamps)} lamps]"

    mi.register_emitter(PLUGIN, lambda props: LampSet(props))
    _REGISTERED.add(mi.variant())


def lamp_set_emitter(spots: dict) -> dict:
    """One Mitsuba emitter dict (a spectral variant must be set) holding the `spot_emitter` dicts
    `spots` (≥ 1), sampled per shading point (module docstring); its sampling_weight, its share
    of Mitsuba's light selection against other emitters, is the sum of theirs."""
    if not spots:
        raise InvalidValueError("lamp set: no lamps given")
    arrays = _spot_arrays(spots)
    key = hashlib.sha1(b"".join(np.ascontiguousarray(v).tobytes() for k, v in arrays.items() if k != "spectra")
                       + repr(arrays["spectra"]).encode()).hexdigest()
    _SETS.pop(key, None)
    _SETS[key] = arrays
    while len(_SETS) > MAX_SETS:                    # the oldest first: a long data set stays small
        _SETS.pop(next(iter(_SETS)))
    _register()
    return {"type": PLUGIN, "set": key, "sampling_weight": float(sum(e["sampling_weight"] for e in spots.values()))}

"""The glowing faces of street-lamp heads at night: seen, never sampled.

A street lamp lights the scene through its point emitter (lamps.street_lamp_emitter: intensity
I(λ) = Φ/(2π) W/sr/nm over the lower hemisphere), which a camera cannot see: alone, a lamp at
night reads as light on the ground under a dark head. Each lamp's clear lens (the 'lens_clear'
quad under its head, scene/city/assets._lamp) therefore gets a face just below it: a horizontal
rectangle facing down, a `lamp_face` emitter of radiance L(λ, θ) = I(λ)/(A cos θ) (A its area, θ
from the downward normal, up to the point emitter's cut-off), so that seen from any direction it
has the point emitter's intensity I(λ) = L·A·cos θ: a pixel that sees the face takes the lamp's
light as a camera would.

The face adds no light to the scene, which the point emitter already carries (the same flux
twice would double the street's illuminance). It is never chosen for next-event estimation
(sampling_weight ~0, and a sample of it is empty), and it reports an infinite direction density,
so that the path integrator's multiple importance weight for a BSDF-sampled ray that reaches it,
p_bsdf² / (p_bsdf² + p_light²), is 0. What remains is a camera ray's first hit and hits after
specular (delta) bounces, whose weight is 1: the face in a puddle's or a window's mirror image,
light the point emitter cannot give (a delta BSDF never meets a point). Mitsuba's `path` and
`volpath` integrators weigh emitter hits this way.
"""
from __future__ import annotations

import hashlib

import numpy as np

from workbench.errors import InvalidValueError

PLUGIN = "lamp_face"
FACE_BELOW_LENS_M = 0.002          # under the lens mesh, above the point emitter (2 cm below the head)
FACE_SAMPLING_WEIGHT = 1e-30       # never picked for next-event estimation; > 0 so that its selection
                                   # probability times the infinite density is ∞ (MIS weight 0), not NaN
_REGISTERED: set[str] = set()
_INTENSITIES: dict[str, object] = {}   # spectrum key → loaded Mitsuba spectrum (one per lamp kind and flux)
MAX_INTENSITIES = 64


def _register() -> None:
    """Register the `lamp_face` emitter plugin for the current Mitsuba variant (once)."""
    import drjit as dr
    import mitsuba as mi

    if mi.variant() in _REGISTERED:
        return

    class LampFace(mi.Emitter):
        """A lamp head's face: radiance I/(A cos θ) toward its front, no light sampled (module docstring)."""

        def __init__(self, props):
            mi.Emitter.__init__(self, props)
            self.m_flags = mi.EmitterFlags.Surface
            self.intensity = _INTENSITIES[props["intensity"]]      # a spectrum texture, W/sr/nm
            self.area_m2 = float(props["area_m2"])
            self.min_cos = float(props["min_cos"])
            self.lamp = int(props["lamp"])         # which lamp (also keeps equal faces' dicts distinct)

        def _radiance(self, wavelengths, cos_e, active):
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.wavelengths = wavelengths
            ok = active & (cos_e >= self.min_cos)
            value = self.intensity.eval(si, ok) / (self.area_m2 * dr.maximum(cos_e, self.min_cos))
            return dr.select(ok, value, 0.0)

        def eval(self, si, active=True):
            return self._radiance(si.wavelengths, mi.Frame3f.cos_theta(si.wi), active)

        def sample_direction(self, it, sample, active=True):
            ds = dr.zeros(mi.DirectionSample3f)
            ds.emitter = mi.EmitterPtr(self)
            return ds, dr.zeros(mi.Spectrum)

        def pdf_direction(self, it, ds, active=True):
            return dr.select(active, dr.inf, 0.0)

        def eval_direction(self, it, ds, active=True):
            return dr.zeros(mi.Spectrum)

        def traverse(self, callback):
            pass

        def to_string(self):
            return f"LampFace[area {self.area_m2:.3f} m²]"

    mi.register_emitter(PLUGIN, lambda props: LampFace(props))
    _REGISTERED.add(mi.variant())


def lens_rectangle(vertices_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
    """(centre, unit long axis in the horizontal plane, (half long, half short) m) of a horizontal
    rectangular lens given by its vertices (V×3, any order)."""
    v = np.asarray(vertices_m, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3 or not np.all(np.isfinite(v)):
        raise InvalidValueError(f"a lamp lens needs ≥ 3 finite vertices (V×3), got shape {v.shape}")
    if np.ptp(v[:, 2]) > 1e-3:
        raise InvalidValueError(f"a lamp lens must be horizontal; its vertices span {np.ptp(v[:, 2]):.3f} m in height")
    centre = v.mean(0)
    xy = v[:, :2] - centre[:2]
    _, vecs = np.linalg.eigh(xy.T @ xy)
    axis = vecs[:, -1]
    long, short = np.abs(xy @ axis).max(), np.abs(xy @ np.array([-axis[1], axis[0]])).max()
    if not (long > 0 and short > 0):
        raise InvalidValueError("a lamp lens has no area")
    return centre, np.r_[axis, 0.0], (float(long), float(short))


def lamp_face_shape(lens_vertices_m: np.ndarray, intensity_spectrum: dict, cutoff_deg: float, lamp: int = 0) -> dict:
    """Mitsuba shape dict (a spectral variant must be set) of the face under a lamp's lens: a
    rectangle FACE_BELOW_LENS_M under it, facing down, with a `lamp_face` emitter of the point
    emitter's intensity (`intensity_spectrum`, a Mitsuba spectrum dict in W/sr/nm) out to
    cutoff_deg from the vertical; `lamp` numbers it (Mitsuba would merge equal dicts into one
    emitter, which cannot sit on two shapes)."""
    import mitsuba as mi

    if not 0 < cutoff_deg < 90:
        raise InvalidValueError(f"cutoff_deg must be in (0, 90), got {cutoff_deg}")
    centre, axis, (a, b) = lens_rectangle(lens_vertices_m)
    key = hashlib.sha1(repr(intensity_spectrum).encode()).hexdigest()
    if key not in _INTENSITIES:
        _INTENSITIES[key] = mi.load_dict(intensity_spectrum)
        while len(_INTENSITIES) > MAX_INTENSITIES:               # the oldest first
            _INTENSITIES.pop(next(iter(_INTENSITIES)))
    _register()
    angle = float(np.degrees(np.arctan2(axis[1], axis[0])))
    to_world = (mi.ScalarTransform4f().translate((centre - [0.0, 0.0, FACE_BELOW_LENS_M]).tolist())
                .rotate([0, 0, 1], angle).rotate([1, 0, 0], 180).scale([a, b, 1.0]))
    emitter = {"type": PLUGIN, "intensity": key, "area_m2": 4 * a * b,
               "min_cos": float(np.cos(np.radians(cutoff_deg))), "sampling_weight": FACE_SAMPLING_WEIGHT,
               "lamp": int(lamp)}
    black = {"type": "diffuse", "reflectance": {"type": "spectrum", "value": 0.0}}
    return {"type": "rectangle", "to_world": to_world, "emitter": emitter, "bsdf": black}


def lamp_faces(city, night) -> dict[str, tuple[int, dict]]:
    """The faces of the city's street-lamp heads (lamp_face_shape under each lamp's 'lens_clear'
    mesh) with the intensity of its point emitter (lamps.street_lamp_emitter under NightParams
    `night`): {shape id: (lamp instance id, shape dict)}."""
    from workbench.render.lamps import (HEMISPHERE_CUTOFF_DEG, LAMP_WAVELENGTHS_NM, RATED_FLUX_LM,
                                        hemisphere_intensity_cd, luminous_intensity_spectrum)

    flux = RATED_FLUX_LM[night.lamp_kind] if night.lamp_flux_lm is None else float(night.lamp_flux_lm)
    wl = LAMP_WAVELENGTHS_NM
    intensity = {"type": "spectrum", "value": list(zip(wl.tolist(), luminous_intensity_spectrum(
        night.lamp_kind, hemisphere_intensity_cd(flux), wl).tolist()))}
    out = {}
    for obj in (o for o in city.objects if o.class_name == "lamp"):
        lenses = [m.vertices for m in obj.meshes if m.material == "lens_clear"]
        if lenses:
            out[f"lamp_face_{obj.instance_id}"] = (obj.instance_id, lamp_face_shape(
                np.concatenate(lenses), intensity, HEMISPHERE_CUTOFF_DEG, obj.instance_id))
    return out

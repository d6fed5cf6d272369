"""The glowing faces of street-lamp heads and vehicle lights at night: seen, never sampled.

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

Vehicle head- and tail-lights are `spot` emitters (lamps.vehicle_lights), as invisible as the
lamps' points. Each gets a face the same way (vehicle_light_face_shape): upright over its lens,
facing the beam, its radiance the spot's own intensity toward the viewer, I(λ, ω)/(A cos θ), read
from the spot itself (beam, cut-off and low-beam pattern); without it the tail-light of a car
ahead read 0.02 cd/m² for the ~170 cd/m² of a lens that sheds 10 cd.
"""
from __future__ import annotations

import hashlib

import numpy as np

from workbench.errors import InvalidValueError

PLUGIN = "lamp_face"
FACE_BELOW_LENS_M = 0.002          # under the lens mesh, above the point emitter (2 cm below the head)
FACE_AHEAD_OF_LENS_M = 0.002      # a vehicle light's face: just ahead of its lens box, behind its spot (2 cm)
FACE_SAMPLING_WEIGHT = 1e-30       # never picked for next-event estimation; > 0 so that its selection
                                   # probability times the infinite density is ∞ (MIS weight 0), not NaN
_REGISTERED: set[str] = set()
_INTENSITIES: dict[str, object] = {}   # key → a loaded spectrum (per lamp kind and flux) or spot (vehicle lights)
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
            self.area_m2 = float(props["area_m2"])
            self.min_cos = float(props["min_cos"])
            self.lamp = int(props["lamp"])         # which lamp (also keeps equal faces' dicts distinct)
            if "pattern" in props:                 # a spot's I(λ, ω), in the light's own frame
                self.intensity, self.pattern = None, _INTENSITIES[props["pattern"]]
                self.light_frame = [mi.ScalarVector3f(*props[f"light_{a}"]) for a in ("x", "y", "z")]
                self.light_origin = mi.ScalarPoint3f(*props["light_origin"])
            else:                                  # I(λ) alike in every direction inside the cut-off
                self.intensity, self.pattern = _INTENSITIES[props["intensity"]], None      # W/sr/nm

        def _intensity(self, si, active):
            if self.pattern is None:
                return self.intensity.eval(si, active)
            # toward the viewer (the ray's origin) as seen from the spot, not from this point of
            # the face: a pixel then holds I(ω) whatever the lens's size against its distance
            viewer = si.p + si.to_world(si.wi) * si.t
            local = dr.normalize(mi.Vector3f(*(dr.dot(viewer - self.light_origin, axis) for axis in self.light_frame)))
            it = dr.zeros(mi.Interaction3f)
            it.p, it.wavelengths = mi.Point3f(local), si.wavelengths
            ds = dr.zeros(mi.DirectionSample3f)
            ds.d, ds.dist = -local, 1.0                          # the spot sits at its frame's origin
            return self.pattern.eval_direction(it, ds, active)

        def eval(self, si, active=True):
            cos_e = mi.Frame3f.cos_theta(si.wi)
            ok = active & (cos_e >= self.min_cos)
            value = self._intensity(si, ok) / (
                self.area_m2 * dr.maximum(cos_e, self.min_cos))
            return dr.select(ok, value, 0.0)

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
    _loaded(key, intensity_spectrum)
    _register()
    angle = float(np.degrees(np.arctan2(axis[1], axis[0])))
    to_world = (mi.ScalarTransform4f().translate((centre - [0.0, 0.0, FACE_BELOW_LENS_M]).tolist())
                .rotate([0, 0, 1], angle).rotate([1, 0, 0], 180).scale([a, b, 1.0]))
    emitter = {"type": PLUGIN, "intensity": key, "area_m2": 4 * a * b,
               "min_cos": float(np.cos(np.radians(cutoff_deg))), "sampling_weight": FACE_SAMPLING_WEIGHT,
               "lamp": int(lamp)}
    black = {"type": "diffuse", "reflectance": {"type": "spectrum", "value": 0.0}}
    return {"type": "rectangle", "to_world": to_world, "emitter": emitter, "bsdf": black}


def _loaded(key: str, spectrum_or_emitter: dict) -> None:
    import mitsuba as mi
    if key not in _INTENSITIES:
        _INTENSITIES[key] = mi.load_dict(spectrum_or_emitter)
        while len(_INTENSITIES) > MAX_INTENSITIES:               # the oldest first
            _INTENSITIES.pop(next(iter(_INTENSITIES)))


def vehicle_light_face_shape(lens_vertices_m: np.ndarray, spot: dict, pattern_key: str, light: int = 0) -> dict:
    """Mitsuba shape dict of the face of a vehicle light whose lens is the box `lens_vertices_m`
    and whose light is the spot dict `spot` (lamps.spot_emitter or headlight_emitter): an upright
    rectangle over the lens's front, FACE_AHEAD_OF_LENS_M ahead of it and facing the spot's axis,
    with a `lamp_face` emitter of radiance I(λ, ω)/(A cos θ), I the spot's own intensity toward the
    viewer ω (its beam, cut-off and head-light pattern), so that the lamp seen from anywhere holds
    the intensity it sheds there. `pattern_key` names the spot's intensity and pattern (equal for
    spots that differ only in pose: one is loaded for all); `light` numbers the face (see
    lamp_face_shape)."""
    import mitsuba as mi

    from workbench.render.spot_pattern import frame
    origin, left, up, axis = frame(spot)
    if abs(axis[2]) > 1e-6:
        raise InvalidValueError(f"a vehicle light's axis must be horizontal, got {axis.tolist()}")
    v = np.asarray(lens_vertices_m, dtype=np.float64)
    side = np.array([-axis[1], axis[0], 0.0])
    s, z, f = v @ side, v[:, 2], v @ axis
    a, b = np.ptp(s) / 2, np.ptp(z) / 2
    if not (a > 0 and b > 0):
        raise InvalidValueError("a vehicle light's lens has no area facing its axis")
    centre = side * (s.min() + a) + np.array([0.0, 0.0, z.min() + b]) + axis * (f.max() + FACE_AHEAD_OF_LENS_M)
    key = "spot:" + pattern_key        # the same spot at the origin, along +z: one per kind and intensity
    _loaded(key, {k: v for k, v in spot.items() if k not in ("to_world", "sampling_weight")})
    _register()
    to_world = (mi.ScalarTransform4f().look_at(origin=centre.tolist(), target=(centre + axis).tolist(),
                                               up=[0.0, 0.0, 1.0]).scale([a, b, 1.0]))
    cutoff = float(spot["cutoff_angle"])
    emitter = {"type": PLUGIN, "pattern": key, "area_m2": 4 * a * b, "lamp": int(light),
               "light_x": left.tolist(), "light_y": up.tolist(), "light_z": axis.tolist(),
               "light_origin": origin.tolist(),
               "min_cos": float(np.cos(np.radians(min(cutoff, 89.9)))), "sampling_weight": FACE_SAMPLING_WEIGHT}
    black = {"type": "diffuse", "reflectance": {"type": "spectrum", "value": 0.0}}
    return {"type": "rectangle", "to_world": to_world, "emitter": emitter, "bsdf": black}


def vehicle_light_faces(vehicles: dict) -> dict[str, tuple[object, dict]]:
    """The faces of the moving vehicles' head- and tail-lights (vehicle_light_face_shape on each
    light of lamps.vehicle_lights' `vehicles`): {shape id: (vehicle object, shape dict)}."""
    return {f"face_{k}": (obj, vehicle_light_face_shape(lens, spot, key, i))
            for i, (k, (obj, lens, spot, key)) in enumerate(vehicles.items())}


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

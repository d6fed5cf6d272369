"""Night lighting: street-lamp and vehicle-light spectra, photometric calibration, Mitsuba emitters.

Spectra (relative spectral power, generated from analytic shapes; facts from lamp literature):
- 'lps' low-pressure sodium: the Na D doublet 589.0/589.6 nm carries almost all visible power;
  the 818.3/819.5 nm Na doublet adds strong NIR (≈ 0.25 of the D-line power).
- 'hps' high-pressure sodium: pressure-broadened D lines with the self-reversed dip at 589 nm
  (wings peaking near 581 and 597 nm), Na lines at 498, 568, 616 nm, the 819 nm NIR doublet and
  a weak continuum.
- 'led' phosphor-converted white LED (~4000 K): InGaN pump at 450 nm (FWHM ≈ 20 nm) plus a
  YAG:Ce phosphor band centred ≈ 565 nm (FWHM ≈ 130 nm); essentially no power past ~780 nm.
- 'metal_halide' (quartz, Na–Tl–In–Sc): weak continuum plus Hg 436/546/577, In 410/451,
  Tl 535, Na 589 (broad), Sc 500–620 cluster; NIR Na 819 nm.
- 'halogen' headlight: a 3200 K blackbody (tungsten), strong in the NIR.
- 'led_red' tail-light: red AlInGaP LED, 625 nm, FWHM ≈ 18 nm.
Street lamps are full-cut-off point sources: uniform intensity over the lower hemisphere, none
upward (the housing), scaled so that the luminous flux Φ_v = 683 lm/W · ∫ 2π I(λ) V(λ) dλ equals
the rated flux: E_v(d) = Φ_v / (2π d²) straight below at distance d. (A point inside the head
lighting its underside from 5 cm would be a firefly source.) Vehicle lights
are Mitsuba `spot` emitters given their peak luminous intensity (cd): tail-lights a cone, head-lights
a low beam (render/low_beam.py: SAE J1383's pattern as the spot's projection texture, aimed by its
pattern, its axis horizontal). Each emitter's `sampling_weight` (Mitsuba picks the light for
next-event estimation in proportion) is its luminous flux, or for a plain spot an upper bound
peak × cone solid angle, so that the dim tail-lights and the sky glow do not take samples from the
street lamps. With
NightParams.light_selection 'view' (view_light_weights) the loaded scene's weights are then
reset for its camera: a light's share goes with its direct illuminance on the surfaces the camera
sees, the root of Σ over visible points of (I cos θ / r² · visibility)² (the choice that minimises
the summed variance of one-light next-event estimates, Σ_i S_i / p_i), mixed with 10 % of the flux
weights so that every light keeps a share (light it sheds only indirectly or between the coarse
grid's points is still sampled: unbiased, only the noise changes). In a city at night most lamps
light streets the camera does not see, and a head-light 1 m behind the car ahead lights a small
bright patch that flux weights sample as rarely as a lamp three blocks away. Both are one table
per frame; NightParams.light_selection 'shading' (render/lamp_set.py) picks a lamp per shading
point instead, which also serves the points bounced paths reach (the night's fireflies).
Radiometric units: intensity W/sr/nm (energy), like the daylight spectra.
"""
from __future__ import annotations

import numpy as np

from workbench.errors import InvalidValueError
from workbench.spectra import blackbody_spd, luminous_efficiency
from workbench.units import MAX_LUMINOUS_EFFICACY_LM_W

LAMP_KINDS = ("lps", "hps", "led", "metal_halide")
# typical rated luminous flux of a street lamp of each kind (lm): LPS 90 W, HPS 150 W,
# LED ~80 W luminaire, metal halide 150 W
RATED_FLUX_LM = {"lps": 13500.0, "hps": 15000.0, "led": 10000.0, "metal_halide": 12000.0}
LUMINOUS_EFFICACY_LM_W = MAX_LUMINOUS_EFFICACY_LM_W      # lm/W at 555 nm (workbench.units)
VEHICLE_CLASSES = ("car", "bus", "truck")     # objects whose lens_clear / lens_red meshes are lamps
HEMISPHERE_CUTOFF_DEG = 89.9        # street lamps: full cut-off (no light above the horizontal)
# fine grid so that 1-nm-wide lines are resolved (Mitsuba interpolates linearly between samples)
LAMP_WAVELENGTHS_NM = np.arange(300.0, 1100.01, 0.25)


def _g(wl, centre_nm, fwhm_nm, power=1.0):
    """Gaussian line of unit area × power."""
    s = fwhm_nm / 2.3548
    return power * np.exp(-0.5 * ((wl - centre_nm) / s) ** 2) / (s * np.sqrt(2 * np.pi))


def lamp_spectrum(kind: str, wavelengths_nm: np.ndarray = LAMP_WAVELENGTHS_NM) -> np.ndarray:
    """Relative spectral power (W/nm, arbitrary scale, ≥ 0) of a lamp kind (module docstring)."""
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    if kind == "lps":
        return _g(wl, 589.0, 1.0, 0.6) + _g(wl, 589.6, 1.0, 0.4) + _g(wl, 818.9, 1.5, 0.25)
    if kind == "hps":
        return (_g(wl, 581.0, 12.0, 0.35) + _g(wl, 597.0, 16.0, 0.45) + _g(wl, 568.8, 3.0, 0.05)
                + _g(wl, 615.9, 3.0, 0.05) + _g(wl, 498.0, 2.0, 0.03) + _g(wl, 819.0, 3.0, 0.18)
                + 0.0008 * ((wl > 380) & (wl < 1000)))
    if kind == "led":
        return _g(wl, 450.0, 20.0, 0.30) + _g(wl, 565.0, 130.0, 0.70)
    if kind == "metal_halide":
        return (0.0010 * ((wl > 380) & (wl < 1000)) + _g(wl, 435.8, 2.0, 0.04) + _g(wl, 546.1, 2.0, 0.06)
                + _g(wl, 577.5, 2.0, 0.03) + _g(wl, 410.2, 2.0, 0.04) + _g(wl, 451.1, 2.0, 0.06)
                + _g(wl, 535.0, 2.0, 0.10) + _g(wl, 589.3, 8.0, 0.12) + _g(wl, 560.0, 60.0, 0.15)
                + _g(wl, 819.0, 3.0, 0.04))
    if kind == "halogen":
        return blackbody_spd(3200.0, wl)
    if kind == "led_red":
        return _g(wl, 625.0, 18.0)
    raise InvalidValueError(f"unknown lamp kind {kind!r}; known: {', '.join(LAMP_KINDS + ('halogen', 'led_red'))}")


def luminous_intensity_spectrum(kind: str, intensity_cd: float,
                                wavelengths_nm: np.ndarray = LAMP_WAVELENGTHS_NM) -> np.ndarray:
    """Radiant intensity I(λ) (W/sr/nm) of the lamp's spectrum scaled to `intensity_cd` candela:
    683 ∫ I V dλ = intensity_cd."""
    if not intensity_cd > 0:
        raise InvalidValueError(f"intensity_cd must be > 0, got {intensity_cd}")
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    s = lamp_spectrum(kind, wl)
    lum = LUMINOUS_EFFICACY_LM_W * np.trapezoid(s * luminous_efficiency(wl), wl)
    return s * (intensity_cd / lum)


def hemisphere_intensity_cd(flux_lm: float) -> float:
    """Luminous intensity (cd) of a source spreading `flux_lm` evenly over a hemisphere: Φ/(2π)."""
    if not flux_lm > 0:
        raise InvalidValueError(f"flux_lm must be > 0, got {flux_lm}")
    return float(flux_lm / (2 * np.pi))


def _spectrum(kind: str, intensity_cd: float) -> dict:
    wl = LAMP_WAVELENGTHS_NM
    return {"type": "spectrum", "value": list(zip(wl.tolist(),
                                                   luminous_intensity_spectrum(kind, intensity_cd, wl).tolist()))}


def street_lamp_emitter(position_m, kind: str, flux_lm: float | None = None) -> dict:
    """Mitsuba emitter of a full-cutoff street lamp of `kind` at position_m: luminous flux
    `flux_lm` (default RATED_FLUX_LM[kind]) spread evenly over the lower hemisphere, I = Φ/(2π),
    none upward (the luminaire housing)."""
    if kind not in LAMP_KINDS:
        raise InvalidValueError(f"street lamp kind must be one of {LAMP_KINDS}, got {kind!r}")
    flux = RATED_FLUX_LM[kind] if flux_lm is None else float(flux_lm)
    return spot_emitter(position_m, (0.0, 0.0, -1.0), kind, hemisphere_intensity_cd(flux),
                        cutoff_deg=HEMISPHERE_CUTOFF_DEG, beam_deg=HEMISPHERE_CUTOFF_DEG - 0.1)


def spot_emitter(position_m, direction, kind: str, peak_cd: float, cutoff_deg: float,
                 beam_deg: float) -> dict:
    """Mitsuba `spot` emitter: `peak_cd` along `direction`, full within beam_deg, 0 past cutoff_deg
    (a smooth falloff between)."""
    import mitsuba as mi

    p = np.asarray(position_m, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    up = [0.0, 0.0, 1.0] if abs(d[2]) < 0.9 else [1.0, 0.0, 0.0]
    return {"type": "spot", "cutoff_angle": float(cutoff_deg), "beam_width": float(beam_deg),
            "sampling_weight": float(peak_cd * cone_solid_angle_sr(cutoff_deg)),   # ≥ its flux (lm)
            "to_world": mi.ScalarTransform4f().look_at(origin=p.tolist(), target=(p + d).tolist(), up=up),
            "intensity": _spectrum(kind, peak_cd)}


def headlight_emitter(position_m, direction, kind: str, peak_cd: float) -> dict:
    """Mitsuba `spot` emitter of a low-beam head-light (render/low_beam.py) at position_m, its axis
    the horizontal `direction` the vehicle faces: the pattern as the spot's projection texture,
    peak_cd at its hot spot (1.5° down, 2° right); sampling_weight its luminous flux (lm)."""
    from workbench.render.low_beam import TEXTURE_CUTOFF_DEG, low_beam_flux_lm, low_beam_texture

    d = np.asarray(direction, dtype=np.float64)
    if abs(d[2]) > 1e-9 * np.linalg.norm(d):
        raise InvalidValueError(f"head-light direction must be horizontal (the pattern is aimed in its own "
                                f"frame), got {d.tolist()}")
    spot = spot_emitter(position_m, d, kind, peak_cd, cutoff_deg=TEXTURE_CUTOFF_DEG,
                        beam_deg=TEXTURE_CUTOFF_DEG - 0.5)
    spot["texture"] = low_beam_texture()
    spot["sampling_weight"] = low_beam_flux_lm(peak_cd)
    return spot


def cone_solid_angle_sr(cutoff_deg: float) -> float:
    """Solid angle (sr) of a cone of half-angle cutoff_deg: 2π(1 − cos)."""
    return float(2 * np.pi * (1 - np.cos(np.radians(cutoff_deg))))


def _lamp_head_points(city) -> list[np.ndarray]:
    """Emitter points of the city's street lamps: 2 cm below the centre of each lamp's luminaire
    head, the part of its highest 'metal_dark' mesh above its 'lens_clear' lens (assets._lamp
    merges the pole's dark foot and the head into one mesh: its lowest point is the foot, on the
    sidewalk; a lamp without a lens: the whole mesh)."""
    points = []
    for obj in city.objects:
        if obj.class_name != "lamp":
            continue
        heads = [m.vertices for m in obj.meshes if m.material == "metal_dark"]
        if not heads:
            raise InvalidValueError(f"lamp {obj.instance_id} has no 'metal_dark' luminaire head mesh")
        head = max(heads, key=lambda v: v[:, 2].max())
        lenses = [m.vertices for m in obj.meshes if m.material == "lens_clear"]
        if lenses:
            head = head[head[:, 2] >= np.concatenate(lenses)[:, 2].max()]
            if not len(head):
                raise InvalidValueError(f"lamp {obj.instance_id}: its 'lens_clear' lens lies above its "
                                        f"'metal_dark' head; put the lens under the head")
        lo, hi = head.min(0), head.max(0)
        points.append(np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2] - 0.02]))
    return points


def _vehicle_light_points(obj, material: str) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(position, outward horizontal direction, lens vertices) of the left and right lamps of a
    vehicle made of the `material` mesh (two lamp boxes, split across the vehicle's width)."""
    lenses = [m.vertices for m in obj.meshes if m.material == material]
    if not lenses:
        return []
    v = np.concatenate(lenses)
    body = np.concatenate([m.vertices for m in obj.meshes])
    centre = body.mean(0)
    out = v.mean(0) - centre
    out[2] = 0.0
    out /= np.linalg.norm(out)
    side = np.array([-out[1], out[0], 0.0])
    s = (v - v.mean(0)) @ side
    result = []
    for half in (s < 0, s >= 0):
        if half.any():
            p = v[half]
            lo, hi = p.min(0), p.max(0)
            front = ((p - centre) @ out).max()
            pos = (lo + hi) / 2
            pos = pos + out * (front - (pos - centre) @ out + 0.02)      # 2 cm in front of the lens
            result.append((pos, out, p))
    return result


def vehicle_lights(city, night) -> dict[str, tuple[object, np.ndarray, dict, str]]:
    """The head- and tail-lights of the city's moving vehicles under NightParams `night` (none
    when night.vehicle_lights is off): {emitter id: (vehicle object, lens vertices, spot dict,
    pattern key)}; lights of one pattern key differ only in where they sit and point."""
    out = {}
    if not night.vehicle_lights:
        return out
    head_key = f"headlight:{night.headlight_kind}:{night.headlight_cd!r}"
    tail_key = f"taillight:led_red:{night.taillight_cd!r}:{TAILLIGHT_CUTOFF_DEG}:{TAILLIGHT_BEAM_DEG}"
    for obj in (o for o in city.objects if o.class_name in VEHICLE_CLASSES and not o.meta.get("parked")):
        for j, (p, d, lens) in enumerate(_vehicle_light_points(obj, "lens_clear")):
            out[f"headlight_{obj.instance_id}_{j}"] = (obj, lens, headlight_emitter(
                p, d, night.headlight_kind, night.headlight_cd), head_key)
        for j, (p, d, lens) in enumerate(_vehicle_light_points(obj, "lens_red")):
            out[f"taillight_{obj.instance_id}_{j}"] = (obj, lens, spot_emitter(
                p, d, "led_red", night.taillight_cd, cutoff_deg=TAILLIGHT_CUTOFF_DEG, beam_deg=TAILLIGHT_BEAM_DEG),
                tail_key)
    return out


TAILLIGHT_CUTOFF_DEG, TAILLIGHT_BEAM_DEG = 60.0, 20.0


def tunnel_emitters(city, sampling_weight: float | None = None, exterior=None,
                    sun_shares: dict | None = None) -> dict[str, tuple[int, object]]:
    """The glowing lenses of every tunnel's luminaires (scene/city/tunnel.py) as one Mitsuba mesh
    per tunnel with one emitter that samples its whole row (render/luminaire_row.py): {shape id:
    (tunnel instance id, mesh)}. Each lens is a Lambertian emitter of the tunnel's kind whose
    luminous flux is the luminaire's: on-axis intensity I₀ = Φ/π, radiance I₀(λ)/A. sampling_weight:
    the row's share of Mitsuba's light selection (by day 1, like the sun and the sky); None = its
    total flux (lm), as the street lamps at night. exterior: a loaded medium around the lenses.
    sun_shares: {tunnel instance id: its row's weight and the sun it carries} (by day with a sun:
    tunnel_sun_share.row_sun_shares); such a row's emitter picks the sun or the row per point."""
    from workbench.render.luminaire_row import luminaire_row_shape

    out = {}
    for obj in (o for o in city.objects if o.class_name == "tunnel"):
        kind, flux = obj.meta["luminaire_kind"], float(obj.meta["luminaire_flux_lm"])
        centres = np.asarray(obj.meta["luminaires_m"], dtype=np.float64)
        hx, hy = obj.meta["lens_half_size_m"]
        wl = LAMP_WAVELENGTHS_NM
        radiance = luminous_intensity_spectrum(kind, flux / np.pi, wl) / (4 * hx * hy)
        weight = flux * len(centres) if sampling_weight is None else sampling_weight
        share = (sun_shares or {}).get(obj.instance_id)
        spectrum = {"type": "spectrum", "value": list(zip(wl.tolist(), radiance.tolist()))}
        sid = f"tunnel_{obj.instance_id}_lenses"
        out[sid] = (obj.instance_id, luminaire_row_shape(sid, centres, (hx, hy), spectrum, weight, exterior)
                    if share is None else
                    luminaire_row_shape(sid, centres, (hx, hy), spectrum, share["sampling_weight"], exterior,
                                        share["plugin"], share["sun"]))
    return out


def night_emitters(city, night, vehicles: dict | None = None) -> dict:
    """Mitsuba emitters of a night scene (NightParams): street lamps, vehicle lights (not of parked
    cars; `vehicles`: vehicle_lights(city, night) when the caller has it already), sky glow. With
    night.light_selection 'shading' the lamps and vehicle lights are one emitter, LAMP_SET_ID
    (render/lamp_set.py), weighing their summed weights."""
    from workbench.render.daylight import DAYLIGHT_WAVELENGTHS_NM

    out = {}
    for i, p in enumerate(_lamp_head_points(city)):
        out[f"street_lamp_{i}"] = street_lamp_emitter(p, night.lamp_kind, night.lamp_flux_lm)
    vehicles = vehicle_lights(city, night) if vehicles is None else vehicles
    out.update({k: spot for k, (_, _, spot, _) in vehicles.items()})
    if night.light_selection == "shading" and out:
        from workbench.render.lamp_set import lamp_set_emitter
        out = {LAMP_SET_ID: lamp_set_emitter(out)}
    if night.sky_luminance_cd_m2 > 0:
        wl = DAYLIGHT_WAVELENGTHS_NM
        shape = blackbody_spd(3500.0, wl)
        lum = LUMINOUS_EFFICACY_LM_W * np.trapezoid(shape * luminous_efficiency(wl), wl)
        sky = shape * (night.sky_luminance_cd_m2 / lum)
        weight = 0.01 * sum(e.get("sampling_weight", 0.0) for e in out.values()) or 1.0
        out["sky"] = {"type": "constant", "sampling_weight": weight,
                      "radiance": {"type": "spectrum", "value": list(zip(wl.tolist(), sky.tolist()))}}
    return out


LAMP_SET_ID = "street_lights"      # the one emitter of all lamps with light_selection 'shading'
DEFENSIVE_SHARE = 0.1          # of the selection probability kept in proportion to flux (view weights)
IMPORTANCE_GRID_PX = 96 * 72   # most visible points the view weights are estimated on


def spot_importance(points_m: np.ndarray, normals: np.ndarray, emitter: dict) -> np.ndarray:
    """Direct illuminance proxy (cd/m², unit reflectance) of a spot_emitter dict at each point
    (P×3, normals P×3, either side): its intensity toward the point (peak × falloff × texture,
    render/spot_pattern.py) × |cos θ| / r², no visibility."""
    from workbench.render import spot_pattern

    origin = spot_pattern.frame(emitter)[0]
    v = np.asarray(points_m, dtype=np.float64) - origin
    r2 = np.maximum(np.einsum("ij,ij->i", v, v), 1e-12)
    u = v / np.sqrt(r2)[:, None]
    cd = spot_pattern.peak_cd(emitter) * spot_pattern.relative_intensity(emitter, u)
    return cd * np.abs(np.einsum("ij,ij->i", u, np.asarray(normals))) / r2


def camera_grid_hits(mi_scene, max_points: int):
    """(rays, their first hits) of the scene's camera through pixel centres of a regular grid of at
    most max_points points over its film."""
    import drjit as dr
    import mitsuba as mi

    sensor = mi_scene.sensors()[0]
    w, h = (int(v) for v in sensor.film().crop_size())
    step = max(1, int(np.ceil(np.sqrt(w * h / max_points))))
    gw, gh = max(1, w // step), max(1, h // step)
    idx = dr.arange(mi.UInt32, gw * gh)
    ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f((mi.Float(idx % gw) + 0.5) / gw, (mi.Float(idx // gw) + 0.5) / gh),
                               mi.Point2f(0.5, 0.5))
    return ray, mi_scene.ray_intersect(ray)


def view_light_weights(mi_scene, emitters: dict, *, defensive: float = DEFENSIVE_SHARE) -> dict[str, float]:
    """Sampling weights of the spot emitters (by id) for the scene's camera (module docstring):
    total(flux weights) × [(1 − defensive) √S_i / Σ√S + defensive · flux_i / Σ flux], S_i the sum of
    squared spot_importance × visibility over first hits of pixel-centre rays on a grid of at most
    IMPORTANCE_GRID_PX points. Other emitters (the sky glow, tunnel luminaire rows) keep theirs."""
    import mitsuba as mi

    spots = {k: e for k, e in emitters.items() if isinstance(e, dict) and e.get("type") == "spot"}
    if not spots:
        return {}
    _, si = camera_grid_hits(mi_scene, IMPORTANCE_GRID_PX)
    hit = np.array(si.is_valid(), dtype=bool)
    pts = np.stack([np.array(c, dtype=np.float64) for c in (si.p.x, si.p.y, si.p.z)], -1)[hit]
    nrm = np.stack([np.array(c, dtype=np.float64) for c in (si.n.x, si.n.y, si.n.z)], -1)[hit]
    flux = np.array([e["sampling_weight"] for e in spots.values()])
    root_s = np.zeros(len(spots))
    for i, e in enumerate(spots.values()):
        f = spot_importance(pts, nrm, e)
        lit = f > 0
        if lit.any():
            origin = np.array(e["to_world"].matrix, dtype=np.float64)[:3, 3]
            to_light = origin - pts[lit]
            dist = np.linalg.norm(to_light, axis=1)
            d = to_light / dist[:, None]
            start = pts[lit] + np.copysign(1e-3, np.einsum("ij,ij->i", nrm[lit], d))[:, None] * nrm[lit]
            shadow = mi.Ray3f(mi.Point3f(*start.T.astype(np.float32)), mi.Vector3f(*d.T.astype(np.float32)))
            shadow.maxt = mi.Float((dist * (1 - 1e-4) - 1e-3).astype(np.float32))
            f[np.flatnonzero(lit)[np.array(mi_scene.ray_test(shadow), dtype=bool)]] = 0.0
        root_s[i] = np.sqrt(np.sum(f ** 2))
    if not root_s.sum() > 0:
        return dict(zip(spots, flux.tolist()))
    share = (1 - defensive) * root_s / root_s.sum() + defensive * flux / flux.sum()
    return dict(zip(spots, (flux.sum() * share).tolist()))


def set_view_light_weights(mi_scene, emitters: dict) -> dict[str, float]:
    """Reset the loaded scene's spot sampling weights to view_light_weights (in place); returns them."""
    import mitsuba as mi

    weights = view_light_weights(mi_scene, emitters)
    params = mi.traverse(mi_scene)
    for name, wt in weights.items():
        params[f"{name}.sampling_weight"] = float(wt)
    params.update()
    return weights

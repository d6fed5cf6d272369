"""Fog by Koschmieder's law (FogParams.model 'koschmieder'; fog.py holds the medium itself).

FogParams.model 'koschmieder' renders the city in clear air (path integrator; the direct sun
dimmed to e^{−σH/sin el}, what reaches the ground through the layer: sun_through_layer) and fogs
each pixel afterwards (KoschmiederFog.apply): L = L₀ e^{−σd} + ∫₀^d σ e^{−σt} J(z(t)) dt, d the
pixel-centre ray's path inside the same layer box (to its first hit, or to where it leaves the
box: sky pixels keep L₀ e^{−σd} of the sky above the layer, as the volumetric model's rays do).
With J constant this is Koschmieder's law L₀T + L_air(1 − T). J, the fog's source function
(in-scattered radiance, albedo × ∫ p L dω), is measured per frame on an empty layer over the
ground by small volpath renders: for level and falling rays as a function of height J(z)
(airlight_profile: an orthographic camera whose rows are horizontal rays at different heights —
a horizontal ray in a horizontally uniform layer sees the same J all along it, so its radiance
is J(z), Koschmieder's horizon-sky luminance at every height); for rising rays as the mean
along the ray J̄(θ) by elevation (upward_airlight: forward-peaked droplet scattering makes fog
seen upward much brighter than seen level). What it leaves out, and the volumetric model keeps:
J's change with azimuth within the view (sun glow), the fog's diffuse light on objects (the
clear sky stands in for it), objects' own shadow on the fog before them, shadowed fog between
buildings, lamp halos at night (the night source is the sky glow's alone), the fog's dimming of
a lamp's light on its way to a surface (only the sun is dimmed: at V = 50 m a floor 8.5 m from a
street lamp keeps 0.93 of its clear-air light here, 0.88 in the volumetric model at albedo 0.98,
0.64 at albedo 0.5; night fog studies want 'volumetric'), and pixels whose footprint spans
several depths (the pixel-centre ray's d is used). On the render bench's city
view (V = 150 m, a 60 m layer, sun 45°) it comes within a few % of the volumetric reference in
the frame mean (objects and sky separately), at ~10⁻³ of its cost (`workbench bench render`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.errors import InvalidValueError
from workbench.render.fog import (FOG_BOX_ID, box_bounds_m, exit_distance_m, extinction_per_m, fog_box, fog_medium,
                                  pixel_directions, transmittance)

AIRLIGHT_ROWS = 8                   # heights of the source profile through the layer (rows)
AIRLIGHT_COLUMNS = 32
AIRLIGHT_SPP = 2048
AIRLIGHT_OPTICAL_RADIUS = 25.0      # the empty layer's half-width in optical depths (e^{−25} ≈ 1e−11)
PATH_SAMPLES = 16                   # optical-depth quadrature points along each pixel ray
UPWARD_BINS = 16                    # elevation bins of the upward airlight
UPWARD_COLUMNS, UPWARD_ROWS = 48, 32
UPWARD_SPP = 256


def _empty_layer(film, fog, lights: dict, ground_reflectance: dict, camera: dict, *, foggy: bool, max_depth: int,
                 spp: int, seed: int) -> np.ndarray:
    """Radiance (H×W×Nλ, film output) seen by the Mitsuba sensor dict `camera` (film and sampler
    added here) in an empty fog layer: a box of half-width AIRLIGHT_OPTICAL_RADIUS/σ about the
    origin, z −1…fog.height_m, over a ground plane of `ground_reflectance` (a Mitsuba spectrum
    dict), lit by `lights` (Mitsuba emitter dicts); volpath, or the clear air (path) unless foggy."""
    import mitsuba as mi

    from workbench.jobs import run_job
    from workbench.render.params import RenderParams
    from workbench.render.spectral import render_loaded

    radius = AIRLIGHT_OPTICAL_RADIUS / extinction_per_m(fog.visibility_m)
    ground = {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale([radius, radius, 1.0]),
              "bsdf": {"type": "diffuse", "reflectance": ground_reflectance}}
    scene = {"type": "scene", "sensor": {**camera, "sampler": {"type": "independent", "sample_count": 1}},
             **lights, "ground": ground, "integrator": {"type": "volpath" if foggy else "path",
                                                         "max_depth": int(max_depth)}}
    if foggy:
        medium = fog_medium(fog)
        scene["sensor"]["medium"] = medium
        ground["exterior"] = medium
        scene[FOG_BOX_ID] = fog_box(medium, (-radius, -radius, radius, radius), fog.height_m, margin_m=0.0)
    p = RenderParams(spp=spp, chunk_spp=spp, preview_spp=spp, seed=seed)
    return run_job(render_loaded(mi.load_dict(scene), film, p, fov_deg=1.0)).radiance_photons.astype(np.float64)


def airlight_profile(film, fog, lights: dict, ground_reflectance: dict, pan_deg: float, *, max_depth: int = 6,
                     spp: int = AIRLIGHT_SPP, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The fog's source function J(z) (film output spectra, photons/s/sr/m²/nm) at AIRLIGHT_ROWS heights
    z (m) through the layer: the radiance of horizontal rays toward pan_deg in the empty layer
    (_empty_layer), rendered through an orthographic camera whose rows are the heights. A
    horizontal ray in a horizontally uniform layer sees the same J all along it, so its radiance
    is J. Returns (z_m (rows,), J (rows × Nλ))."""
    import mitsuba as mi

    top = float(fog.height_m)
    fwd = np.array([np.cos(np.radians(pan_deg)), np.sin(np.radians(pan_deg)), 0.0])
    centre = np.array([0.0, 0.0, top / 2])
    half = top / 2 * AIRLIGHT_COLUMNS / AIRLIGHT_ROWS     # Mitsuba's view spans ±1/aspect vertically
    radius = AIRLIGHT_OPTICAL_RADIUS / extinction_per_m(fog.visibility_m)
    cam = {"type": "orthographic", "near_clip": 1e-3, "far_clip": 4 * radius,
           "to_world": mi.ScalarTransform4f().look_at(origin=centre.tolist(), target=(centre + fwd).tolist(),
                                                      up=[0.0, 0.0, 1.0])
           @ mi.ScalarTransform4f().scale([half, half, 1.0]),
           "film": film.mitsuba_film(AIRLIGHT_COLUMNS, AIRLIGHT_ROWS)}
    rad = _empty_layer(film, fog, lights, ground_reflectance, cam, foggy=True, max_depth=max_depth, spp=spp,
                       seed=seed)
    z = top * (1.0 - (np.arange(AIRLIGHT_ROWS) + 0.5) / AIRLIGHT_ROWS)        # row 0 = the top
    return z[::-1], rad.mean(axis=1)[::-1]


def upward_airlight(film, fog, lights: dict, ground_reflectance: dict, height_m: float, pan_deg: float,
                    max_elevation_deg: float, *, max_depth: int = 6, spp: int = UPWARD_SPP,
                    seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The mean source function J̄(θ) along upward rays (film output spectra) at UPWARD_BINS
    elevations θ in 0…max_elevation_deg (bin centres, deg), from height_m toward pan_deg: a rising
    ray leaves the empty layer at distance t, and its radiance is J̄(1 − e^{−σt}) + e^{−σt} L_sky
    with J̄ the e^{−σs}-weighted mean source along it; so J̄ = Σ(L_fog − T L_clear) / Σ(1 − T) over
    the pixels of a perspective render of the empty layer (_empty_layer, with and without fog) in
    each elevation bin. Forward-peaked droplet scattering makes J̄ grow with θ (the light in fog
    travels mostly downward), which the horizontal profile J(z) misses."""
    import mitsuba as mi

    from workbench.render.scene_builder import pinhole_sensor
    from workbench.scene.city.types import CameraPose

    top_deg = float(np.clip(max_elevation_deg, 1.0, 89.0))
    pose = CameraPose(np.array([0.0, 0.0, float(height_m)]), float(pan_deg), top_deg / 2, 0.0)
    cam = {**pinhole_sensor(pose, 1.0), "fov": top_deg * 1.02, "fov_axis": "y",
           "film": film.mitsuba_film(UPWARD_COLUMNS, UPWARD_ROWS)}
    fogged = _empty_layer(film, fog, lights, ground_reflectance, cam, foggy=True, max_depth=max_depth, spp=spp,
                          seed=seed)
    clear = _empty_layer(film, fog, lights, ground_reflectance, cam, foggy=False, max_depth=max_depth, spp=spp,
                         seed=seed + 1)
    radius = AIRLIGHT_OPTICAL_RADIUS / extinction_per_m(fog.visibility_m)
    lo, hi = box_bounds_m((-radius, -radius, radius, radius), fog.height_m, 0.0)
    dirs = pixel_directions(mi.load_dict({"type": "scene", "sensor": cam}))[1]
    t = transmittance(extinction_per_m(fog.visibility_m), exit_distance_m([0.0, 0.0, height_m], dirs, lo, hi))
    elevation = np.degrees(np.arcsin(np.clip(dirs[..., 2], -1.0, 1.0)))
    edges = np.linspace(0.0, top_deg, UPWARD_BINS + 1)
    which = np.clip(np.digitize(elevation, edges) - 1, 0, UPWARD_BINS - 1)
    num = np.zeros((UPWARD_BINS, fogged.shape[-1]))
    den = np.zeros(UPWARD_BINS)
    np.add.at(num, which.ravel(), (fogged - t[..., None] * clear).reshape(-1, fogged.shape[-1]))
    np.add.at(den, which.ravel(), (1.0 - t).ravel())
    return 0.5 * (edges[1:] + edges[:-1]), num / np.maximum(den, 1e-12)[:, None]


def path_airlight(origin_z_m: float, directions_z, path_m, sigma_per_m: float, z_m, source) -> np.ndarray:
    """∫₀^s σ e^{−σt} J(z₀ + t d_z) dt along each ray (directions_z: the rays' z components, path_m
    their lengths s; J tabulated as source (rows × Nλ) at heights z_m, held constant beyond them):
    midpoint quadrature in u = 1 − e^{−σt} over PATH_SAMPLES points, J linear in z. Returns …×Nλ."""
    dz = np.asarray(directions_z, dtype=np.float64)
    s = np.asarray(path_m, dtype=np.float64)
    reach = 1.0 - transmittance(sigma_per_m, s)                           # 1 − T(s)
    u = (np.arange(PATH_SAMPLES) + 0.5) / PATH_SAMPLES
    t = -np.log1p(-reach[..., None] * u) / sigma_per_m                    # …×n distances
    z = np.clip(origin_z_m + t * dz[..., None], z_m[0], z_m[-1])
    i = np.clip(np.searchsorted(z_m, z, side="right") - 1, 0, len(z_m) - 2)
    f = (z - z_m[i]) / (z_m[i + 1] - z_m[i])
    pix = np.arange(s.size).reshape(s.shape)[..., None]
    weights = np.zeros(s.size * len(z_m))                                # per pixel × height: Σ interp. weights
    np.add.at(weights, (pix * len(z_m) + i).ravel(), (1 - f).ravel())
    np.add.at(weights, (pix * len(z_m) + i + 1).ravel(), f.ravel())
    w = weights.reshape(s.size, len(z_m)) * (reach.reshape(-1, 1) / PATH_SAMPLES)
    return (w @ np.asarray(source, dtype=np.float64)).reshape(*s.shape, -1)


@dataclass
class KoschmiederFog:
    """A frame's fog: extinction σ (1/m), each pixel's path in the layer (H×W, m), the in-scattered
    radiance along it (H×W×Nλ) and what it came from: the horizontal source profile J(z) (rays
    level or falling) and the upward mean source J̄(θ) (rising rays)."""

    sigma_per_m: float
    path_m: np.ndarray
    inscattered: np.ndarray
    profile_z_m: np.ndarray
    profile: np.ndarray
    upward_elevation_deg: np.ndarray
    upward: np.ndarray

    def apply(self, radiance: np.ndarray) -> np.ndarray:
        """The clear-air radiance (H×W×Nλ) seen through the fog: L₀ e^{−σd} + in-scattered."""
        r = np.asarray(radiance)
        return (r * transmittance(self.sigma_per_m, self.path_m)[..., None] + self.inscattered).astype(r.dtype)


GROUND_CLASSES = ("road", "ground", "sidewalk")


def ground_reflectance(city) -> dict:
    """The Mitsuba spectrum of the city's ground under the airlight layer: the first material of its
    road (else ground, else sidewalk) object."""
    for cls in GROUND_CLASSES:
        for obj in city.objects:
            if obj.class_name == cls and obj.meshes:
                m = city.materials[obj.meshes[0].material]
                return {"type": "spectrum", "value": list(zip(np.asarray(m.wavelengths_nm, float).tolist(),
                                                              np.asarray(m.reflectance, float).tolist()))}
    raise InvalidValueError(f"the city has no {'/'.join(GROUND_CLASSES)} object to stand the fog layer on")


def koschmieder_fog(mi_scene, depth_m: np.ndarray, city, pan_deg: float, film, daylight, world,
                    *, max_depth: int = 6, airlight_spp: int = AIRLIGHT_SPP) -> KoschmiederFog:
    """The Koschmieder fog of a clear-air city render (mi_scene built without the medium; depth_m its
    pixel-centre hit distances, labels.BACKGROUND_DEPTH_M for sky): paths inside the layer box
    (fog_box's); in-scattered light along level and falling rays from the source profile J(z)
    (path_airlight), along rising rays from the upward mean source J̄(θ) × (1 − e^{−σd})
    (upward_airlight); the empty layer lit by the daylight or, at night, the sky glow."""
    from workbench.render.lamps import night_emitters
    from workbench.render.sky import daylight_emitters

    fog = world.fog
    centre, dirs = pixel_directions(mi_scene)
    lo, hi = box_bounds_m(city.extent_m, fog.height_m)
    path = np.minimum(np.asarray(depth_m, dtype=np.float64), exit_distance_m(centre, dirs, lo, hi))
    if world.lighting == "night":
        lights = {k: v for k, v in night_emitters(city, world.night).items() if k == "sky"}
    else:
        lights = daylight_emitters(daylight)
    ground = ground_reflectance(city)
    z, source = airlight_profile(film, fog, lights, ground, pan_deg, max_depth=max_depth, spp=airlight_spp)
    sigma = extinction_per_m(fog.visibility_m)
    inscattered = path_airlight(float(centre[2]), dirs[..., 2], path, sigma, z, source)
    rising = dirs[..., 2] > 0
    elevation = np.degrees(np.arcsin(np.clip(dirs[..., 2], -1.0, 1.0)))
    if rising.any():
        el, up = upward_airlight(film, fog, lights, ground, float(centre[2]), pan_deg, float(elevation.max()),
                                 max_depth=max_depth)
        j = np.stack([np.interp(elevation[rising], el, up[:, k]) for k in range(up.shape[1])], axis=-1)
        inscattered[rising] = j * (1.0 - transmittance(sigma, path[rising]))[:, None]
    else:
        el, up = np.zeros(0), np.zeros((0, source.shape[1]))
    return KoschmiederFog(sigma, path, inscattered, z, source, el, up)

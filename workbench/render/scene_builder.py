"""City + camera pose + film + daylight → a loaded Mitsuba scene and its shape → label table.

Every mesh becomes one Mitsuba shape with the id `<class>_<instance>_<k>`; the id table maps
each id (`shape.id()`) to its ShapeLabel. Materials are Lambertian with the city's explicit
spectral reflectance (0 outside its samples, so it must cover the film's range, NIR included),
except window glass with WorldParams.glass 'dielectric' (a thin dielectric pane), paints with
WorldParams.paint 'clearcoat' (a rough dielectric coat over the spectral base), and with
WorldParams.materials 'procedural' the surfaces of scene/city/surfaces.py: `blendbsdf`s of those
Lambertian spectra weighted by baked scalar textures (single-channel raw bitmaps repeated over
planar texture coordinates in metres), wet layers as a smooth water coat (`plastic`, n = 1.33).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.errors import InvalidValueError
from workbench.render.coat_regularization import REGULARIZED_ALPHA, camera_sharp_coat, point_coats_at, regularizing
from workbench.render.sky import daylight_emitters
from workbench.render.film import FilmSRFs
from workbench.render.fog import FOG_BOX_ID, check_camera_inside, fog_box, fog_medium, sun_through_layer
from workbench.render.lamp_heads import lamp_faces, vehicle_light_faces
from workbench.render.lamp_set_cache import cache_candidates
from workbench.render.lamps import night_emitters, set_view_light_weights, tunnel_emitters, vehicle_lights
from workbench.render.portal_guide import guide_toward_portals, roulette_depth, tunnel_portals
from workbench.render.tunnel_sun_share import row_sun_shares
from workbench.render.params import DaylightParams, WorldParams
from workbench.scene.city.surfaces import WATER_IOR, Surface, planar_uv_m, procedural_surfaces
from workbench.scene.city.textures import bake
from workbench.scene.city.types import CameraPose, City, Material


@dataclass(frozen=True)
class ShapeLabel:
    """What a Mitsuba shape belongs to: the label class and the city instance id (> 0)."""

    class_name: str
    instance_id: int


def camera_to_world(pose: CameraPose) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(origin, target, up) for look_at. Positive roll turns the camera's up toward its right."""
    p, r = np.radians(pose.pan_deg), np.radians(pose.roll_deg)
    fwd = pose.forward()
    right = np.array([np.sin(p), -np.cos(p), 0.0])
    up = np.cross(right, fwd)
    up = np.cos(r) * up + np.sin(r) * right
    origin = np.asarray(pose.position_m, dtype=np.float64)
    return origin, origin + fwd, up


def pinhole_sensor(pose: CameraPose, fov_deg: float) -> dict:
    """A Mitsuba perspective (pinhole) sensor: horizontal FOV, looking along the pose."""
    if not 0 < fov_deg < 180:
        raise InvalidValueError(f"fov_deg must be in (0, 180), got {fov_deg}")
    import mitsuba as mi

    origin, target, up = camera_to_world(pose)
    return {"type": "perspective", "fov": float(fov_deg), "fov_axis": "x",
            "near_clip": 0.01, "far_clip": 1.0e5,
            "to_world": mi.ScalarTransform4f().look_at(origin=origin.tolist(), target=target.tolist(),
                                                        up=up.tolist())}


def move_pinhole(mi_scene, pose: CameraPose, fov_deg: float, sensor=None) -> None:
    """Point a loaded scene's pinhole sensor (pinhole_sensor), or the given pinhole `sensor`,
    along another pose, in place."""
    import mitsuba as mi
    params = mi.traverse(mi_scene.sensors()[0] if sensor is None else sensor)
    params["to_world"] = mi.Transform4f(pinhole_sensor(pose, fov_deg)["to_world"].matrix)
    params.update()
    if mi_scene is not None:          # a loaded scene's own camera moved: the coats that stay sharp for it
        point_coats_at(mi_scene, camera_to_world(pose)[0])


def coarse_pinhole(pose: CameraPose, fov_deg: float, film_srfs: FilmSRFs, width: int, height: int,
                   factor: int, sampler: str = "independent"):
    """A pinhole sensor (outside any scene; mi.render takes it) with the same view and film
    channels as a width × height one, on a film `factor` times coarser per side: each of its
    box-filtered pixels covers factor × factor pixels of the full film. width and height must be
    multiples of factor."""
    import mitsuba as mi
    if factor < 1 or width % factor or height % factor:
        raise InvalidValueError(f"a {factor}× coarser film needs width and height divisible by {factor}, "
                                f"got {width}×{height}")
    cam = pinhole_sensor(pose, fov_deg)
    cam["film"] = film_srfs.mitsuba_film(width // factor, height // factor)
    cam["sampler"] = {"type": sampler, "sample_count": 1}
    return mi.load_dict(cam)


def _mesh(mi, name: str, vertices: np.ndarray, faces: np.ndarray, bsdf, exterior=None,
          texcoords: np.ndarray | None = None):
    """A Mitsuba mesh (flat-shaded); `texcoords` (V×2) are per-vertex texture coordinates."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise InvalidValueError(f"mesh '{name}': vertices must be V×3 and faces F×3 (F ≥ 1), got "
                         f"{v.shape} and {f.shape}")
    if f.min() < 0 or f.max() >= len(v) or not np.all(np.isfinite(v)):
        raise InvalidValueError(f"mesh '{name}': face indices outside 0…{len(v) - 1} or non-finite vertices")
    props = mi.Properties()
    if exterior is not None:
        props["exterior"] = exterior
    mesh = mi.Mesh(name, len(v), len(f), props, has_vertex_normals=False,
                   has_vertex_texcoords=texcoords is not None)
    params = mi.traverse(mesh)
    params["vertex_positions"] = type(params["vertex_positions"])(v.astype(np.float32).ravel())
    params["faces"] = type(params["faces"])(f.astype(np.uint32).ravel())
    if texcoords is not None:
        uv = np.asarray(texcoords, dtype=np.float32)
        if uv.shape != (len(v), 2) or not np.all(np.isfinite(uv)):
            raise InvalidValueError(f"mesh '{name}': texcoords must be finite V×2, got {uv.shape}")
        params["vertex_texcoords"] = type(params["vertex_texcoords"])(uv.ravel())
    params.update()
    mesh.set_bsdf(bsdf)
    return mesh


GLASS_MATERIALS = ("glass_dark",)
GLASS_IOR = 1.52         # soda-lime window glass (dispersion < 1 % over 400–1000 nm: ignored)
# Automotive clear coat: an acrylic/polyurethane layer of n ≈ 1.5 over the coloured base coat
# (normal-incidence reflectance ((n−1)/(n+1))² = 4 %). Günther et al. 2005 ("Efficient
# acquisition and realistic rendering of car paint", VMV) model it as a smooth Fresnel dielectric
# over the base; we give it a small GGX roughness α = 0.02 (our choice, at the glossy end of
# 0.02–0.1) so the directional sun can glint off it. Mitsuba's roughplastic loses energy as α
# grows (mitsuba3 issue #1155): under a uniform sky a ρ = 0.5 base reads 1.4 % low at α = 0.02,
# 3 % at 0.05 and 19 % at 0.2 against the closed form L(R + ρ(1 − R)) (tests/render/test_render_paint.py).
PAINT_PREFIX = "paint_"
PAINT_COAT_IOR = 1.5
PAINT_COAT_ALPHA = 0.02


def _spectrum(material: Material, film_range_nm: tuple[float, float]) -> dict:
    """Mitsuba spectrum dict of a material's reflectance, checked to cover the film's range."""
    wl = np.asarray(material.wavelengths_nm, dtype=np.float64)
    refl = np.asarray(material.reflectance, dtype=np.float64)
    if wl.shape != refl.shape or wl.size < 2:
        raise InvalidValueError(f"material '{material.name}': reflectance and wavelengths_nm must be equal "
                         f"length ≥ 2, got {refl.shape} and {wl.shape}")
    if wl[0] > film_range_nm[0] or wl[-1] < film_range_nm[1]:
        raise InvalidValueError(f"material '{material.name}' is defined on {wl[0]:.0f}–{wl[-1]:.0f} nm but "
                         f"the film needs {film_range_nm[0]:.0f}–{film_range_nm[1]:.0f} nm")
    if not np.all(np.isfinite(refl)) or refl.min() < 0 or refl.max() > 1:
        raise InvalidValueError(f"material '{material.name}': reflectance must be finite and in 0…1")
    return {"type": "spectrum", "value": list(zip(wl.tolist(), refl.tolist()))}


def _bsdf(mi, material, film_range_nm: tuple[float, float], glass: str = "diffuse", pane: bool = False,
          paint: str = "diffuse", coat_alpha: float = PAINT_COAT_ALPHA):
    """Mitsuba BSDF of a city material. Window glass with glass='dielectric': a see-through thin
    pane (`thindielectric`) where `pane` (a car's closed glass cabin), else a Fresnel-reflecting
    glass surface over the dark interior (`plastic`: n = 1.52 coat over the material's
    reflectance) for window quads mounted on façades and bus/truck bodies. Paints ('paint_*')
    with paint='clearcoat': `roughplastic` (GGX α = coat_alpha, by default PAINT_COAT_ALPHA,
    n = PAINT_COAT_IOR) over the paint's reflectance, with the linear internal-scattering model
    (nonlinear = false)."""
    if paint not in ("diffuse", "clearcoat"):
        raise InvalidValueError(f"paint must be 'diffuse' or 'clearcoat', got {paint!r}")
    spectrum = _spectrum(material, film_range_nm)
    if glass == "dielectric" and material.name in GLASS_MATERIALS:
        if pane:
            return mi.load_dict({"type": "thindielectric", "int_ior": GLASS_IOR, "ext_ior": 1.0})
        return mi.load_dict({"type": "plastic", "int_ior": GLASS_IOR, "ext_ior": 1.0,
                             "diffuse_reflectance": spectrum})
    if paint == "clearcoat" and material.name.startswith(PAINT_PREFIX):
        return mi.load_dict({"type": "roughplastic", "distribution": "ggx", "alpha": coat_alpha,
                             "int_ior": PAINT_COAT_IOR, "ext_ior": 1.0, "nonlinear": False,
                             "diffuse_reflectance": spectrum})
    return mi.load_dict({"type": "diffuse", "reflectance": spectrum})


UNDERLAY_DEPTH_M = 0.01     # the black sheet under a tunnel's floor (tunnel_underlays)
UNDERLAY_MARGIN_M = 1.0     # how far it reaches past the tunnel's walls and portals


def tunnel_underlays(city: City) -> dict[str, dict]:
    """A black sheet UNDERLAY_DEPTH_M under each tunnel's floor (Mitsuba shape dicts by id). The
    road meets each kerb along a line where neither mesh is hit (one float32 step wide): a ray
    from the ceiling that lands there falls through the city and meets the sky below the horizon
    (the uniform sky is Mitsuba's `constant`, over the whole sphere), 10³× the tunnel's light, a
    white dot (city_tunnel frame 1: 3 of 10⁷ random rays inside the tunnel left through its floor,
    all at a kerb; rays aimed at a kerb line, 7 %). The sheet ends them in the dark: the road's
    light they should have found is lost, a bias of the order of their share (3 × 10⁻⁷ of random rays inside)."""
    import mitsuba as mi

    t = mi.ScalarTransform4f()
    out = {}
    for obj in (o for o in city.objects if o.class_name == "tunnel"):
        f = obj.meta["frame"]
        half_x, half_y = f.half_width_m + UNDERLAY_MARGIN_M, (f.y_north_m - f.y_south_m) / 2 + UNDERLAY_MARGIN_M
        out[f"tunnel_underlay_{obj.instance_id}"] = {
            "type": "rectangle", "bsdf": {"type": "diffuse", "reflectance": {"type": "spectrum", "value": 0.0}},
            "to_world": t.translate([f.x_m, (f.y_south_m + f.y_north_m) / 2, f.road_z_m - UNDERLAY_DEPTH_M])
            @ t.scale([half_x, half_y, 1.0])}
    return out


def texture_dict(mi, weight: np.ndarray, tile_m: float) -> dict:
    """A single-channel raw bitmap texture (values used as-is), repeated every tile_m metres of
    the mesh's texture coordinates, bilinearly filtered."""
    return {"type": "bitmap", "bitmap": mi.Bitmap(np.array(weight[..., None], dtype=np.float32)),   # writable copy
            "raw": True, "wrap_mode": "repeat", "filter_type": "bilinear",
            "to_uv": mi.ScalarTransform3f().scale([1.0 / tile_m, 1.0 / tile_m])}


def lambertian_dict(material: Material, film_range_nm: tuple[float, float]) -> dict:
    return {"type": "diffuse", "reflectance": _spectrum(material, film_range_nm)}


def wet_dict(material: Material, film_range_nm: tuple[float, float]) -> dict:
    """The material under a smooth water film: Fresnel reflection at n = 1.33 over the Lambertian
    substrate, with the light the film traps inside (`nonlinear`): albedo
    (1 − F)·ρ(1 − F̄ᵢ)/(1 − ρF̄ᵢ) for the film's internal diffuse reflectance F̄ᵢ (Lekner & Dorf)."""
    return {"type": "plastic", "int_ior": WATER_IOR, "ext_ior": 1.0, "nonlinear": True,
            "diffuse_reflectance": _spectrum(material, film_range_nm)}


def surface_bsdf(mi, surface: Surface, materials: dict[str, Material], film_range_nm: tuple[float, float],
                 seed: int):
    """Nested `blendbsdf`s of a procedural surface: each layer's weight 1 selects its material
    (Lambertian, or under a water film when wet), 0 keeps what lies below. Blendbsdf takes its
    two nested BSDFs in name order: 'below' (weight 0), then 'layer' (weight 1)."""
    def material(name):
        if name not in materials:
            raise InvalidValueError(f"procedural surface uses material '{name}', which the city does not define")
        return materials[name]

    bsdf = lambertian_dict(material(surface.base), film_range_nm)
    for layer in surface.layers:
        top = (wet_dict if layer.wet else lambertian_dict)(material(layer.material), film_range_nm)
        t = layer.texture
        weight = bake(t.kind, t.size_px, int(seed), t.fraction, t.strength)
        bsdf = {"type": "blendbsdf", "weight": texture_dict(mi, weight, t.tile_m), "below": bsdf, "layer": top}
    return mi.load_dict(bsdf)


def build_scene(city: City, pose: CameraPose, fov_deg: float, width: int, height: int,
                film_srfs: FilmSRFs, daylight: DaylightParams, sensor: dict | None = None, *,
                max_depth: int = 6, world: WorldParams | None = None, sampler: str = "independent"):
    """Load the city into Mitsuba (the spectral variant must already be set: variants.py).

    film_srfs: the film's response curves (film.py: box_bands, raised_cosine_basis,
        sensor_channels), which also fix the wavelength range every spectrum must cover.
    sensor: optional Mitsuba sensor dict (e.g. a lens camera) replacing the pinhole; its
        film and sampler are supplied here. Otherwise a pinhole with horizontal `fov_deg`.
    world: lighting (day: `daylight`; night: lamps.night_emitters, with light_selection 'view'
        the lights' sampling weights set for this camera: lamps.set_view_light_weights, and the
        street lamps' and vehicle lights' glowing faces, seen but never sampled: lamp_heads.lamp_faces
        and vehicle_light_faces, labelled as their lamp or vehicle; a
        tunnel's glowing luminaire lenses either way: lamps.tunnel_emitters; by day the surfaces
        inside a tunnel send part of their samples toward its portals: portal_guide.py), fog (fog.py: with model
        'volumetric' a medium box whose id maps to None in the id table = background; with
        'koschmieder' the scene stays clear, its sun dimmed by the layer, and koschmieder.koschmieder_fog
        fogs the render), glass and materials (WorldParams; procedural textures are seeded by
        city.seed); None = day, clear air, diffuse glass, uniform materials.
    sampler: the Mitsuba sampler type (RenderParams.sampler).
    Returns (mi.Scene, id_table: dict[shape id → ShapeLabel, or None for unlabelled helpers])."""
    import mitsuba as mi

    if "spectral" not in (mi.variant() or ""):
        raise InvalidValueError(f"build_scene needs a spectral Mitsuba variant (call "
                         f"workbench.render.variants.select_variant() first); current: {mi.variant()}")
    if not (1 <= width <= 16384 and 1 <= height <= 16384):
        raise InvalidValueError(f"render resolution must be 1…16384 per side, got {width}×{height}")
    if not 1 <= max_depth <= 64:
        raise InvalidValueError(f"max_depth must be in 1…64, got {max_depth}")
    cam = dict(sensor) if sensor is not None else pinhole_sensor(pose, fov_deg)
    cam["film"] = film_srfs.mitsuba_film(width, height)
    cam["sampler"] = {"type": sampler, "sample_count": 1}
    world = WorldParams() if world is None else world
    if world.fog is not None and world.fog.model == "koschmieder":
        daylight = sun_through_layer(daylight, world.fog)
    night = world.lighting == "night"
    vehicles = vehicle_lights(city, world.night) if night else {}
    lights = night_emitters(city, world.night, vehicles) if night else daylight_emitters(daylight)
    # by day a tunnel's light comes in through its portals: its surfaces aim part of their samples there
    portals = [] if night else tunnel_portals(city, daylight)
    # and its luminaire row carries the sun, each picked where it can shine (tunnel_sun_share.py)
    sun_shares = row_sun_shares(city, portals, lights.get("sun")) if portals else {}
    if sun_shares:
        lights.pop("sun")
    faces = lamp_faces(city, world.night) if night else {}      # lamp heads seen glowing (lamp_heads.py)
    light_faces = vehicle_light_faces(vehicles)                  # and vehicle lights
    # there Russian roulette's boost of a dim path meets the sunlit street: none (portal_guide.roulette_depth)
    rr_depth = roulette_depth(portals, max_depth)
    scene = {"type": "scene", "integrator": {"type": "path", "max_depth": int(max_depth), "rr_depth": rr_depth},
             "sensor": cam, **lights}
    id_table: dict[str, ShapeLabel | None] = {}
    medium = None
    if world.fog is not None:
        check_camera_inside(camera_to_world(pose)[0] if sensor is None else
                            np.asarray(cam["to_world"].translation()), city.extent_m, world.fog.height_m)
    if world.fog is not None and world.fog.model == "volumetric":
        medium = fog_medium(world.fog)
        scene["integrator"] = {"type": "volpath", "max_depth": int(max_depth), "rr_depth": rr_depth}
        cam["medium"] = medium
        scene[FOG_BOX_ID] = fog_box(medium, city.extent_m, world.fog.height_m)
        id_table[FOG_BOX_ID] = None
    # a tunnel's luminaires burn by day too: weighing as much as the sky, or (carrying the sun) ROW_AND_SUN_WEIGHT
    lenses = tunnel_emitters(city, None if night else 1.0, medium, sun_shares)
    rng = film_srfs.range_nm
    bsdfs = {}
    coats_regularized = bool(portals) and world.paint == "clearcoat" and regularizing()
    camera_origin = camera_to_world(pose)[0] if sensor is None else np.asarray(cam["to_world"].translation())
    surfaces = procedural_surfaces(world.wet_road_fraction) if world.materials == "procedural" else {}
    for obj in city.objects:
        if obj.instance_id <= 0:
            raise InvalidValueError(f"city object '{obj.class_name}' has instance_id {obj.instance_id}; must be > 0")
        for k, m in enumerate(obj.meshes):
            if m.material not in city.materials:
                raise InvalidValueError(f"mesh {k} of {obj.class_name} {obj.instance_id} uses material "
                                 f"'{m.material}', which the city does not define")
            pane = obj.class_name == "car"              # closed glass cabin: see-through pane
            key = (m.material, pane and m.material in GLASS_MATERIALS)
            if key not in bsdfs:
                if m.material in surfaces:
                    bsdf = surface_bsdf(mi, surfaces[m.material], city.materials, rng, city.seed)
                else:
                    bsdf = _bsdf(mi, city.materials[m.material], rng, world.glass, key[1], world.paint)
                if coats_regularized and m.material.startswith(PAINT_PREFIX) and m.material not in surfaces:
                    # inside a tunnel the light a coat throws on the walls is found blurred (coat_regularization.py)
                    bsdf = camera_sharp_coat(bsdf, _bsdf(mi, city.materials[m.material], rng, world.glass, key[1],
                                                         world.paint, REGULARIZED_ALPHA),
                                             [box for box, _ in portals], camera_origin)
                bsdfs[key] = guide_toward_portals(bsdf, portals)
            sid = f"{obj.class_name}_{obj.instance_id}_{k}"
            if sid in scene:
                raise InvalidValueError(f"duplicate shape id '{sid}': instance ids must be unique")
            if m.material in surfaces:
                v, f, uv = planar_uv_m(m.vertices, m.faces)
                scene[sid] = _mesh(mi, sid, v, f, bsdfs[key], medium, texcoords=uv)
            else:
                scene[sid] = _mesh(mi, sid, m.vertices, m.faces, bsdfs[key], medium)
            id_table[sid] = ShapeLabel(obj.class_name, int(obj.instance_id))
    for sid, (instance_id, mesh) in lenses.items():
        scene[sid] = mesh
        id_table[sid] = ShapeLabel("tunnel", int(instance_id))
    for sid, (instance_id, shape) in faces.items():
        scene[sid] = shape if medium is None else {**shape, "exterior": medium}
        id_table[sid] = ShapeLabel("lamp", int(instance_id))
    for sid, (obj, shape) in light_faces.items():
        scene[sid] = shape if medium is None else {**shape, "exterior": medium}
        id_table[sid] = ShapeLabel(obj.class_name, int(obj.instance_id))
    for sid, shape in tunnel_underlays(city).items():
        scene[sid] = shape if medium is None else {**shape, "exterior": medium}
        id_table[sid] = None
    mi_scene = mi.load_dict(scene)
    if world.lighting == "night" and world.night.light_selection == "view":
        set_view_light_weights(mi_scene, lights)
    if world.lighting == "night" and world.night.light_selection == "shading":
        cache_candidates(mi_scene)
    return mi_scene, id_table


def set_camera_pose(mi_scene, pose: CameraPose) -> None:
    """Move the loaded scene's camera to `pose` in place (no reload, no recompilation)."""
    import mitsuba as mi

    origin, target, up = camera_to_world(pose)
    params = mi.traverse(mi_scene)
    params["sensor.to_world"] = mi.Transform4f().look_at(origin=origin.tolist(), target=target.tolist(),
                                                         up=up.tolist())
    params.update()

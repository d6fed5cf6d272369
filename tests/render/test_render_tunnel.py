"""The tunnel's light and labels (render/luminaire_row.py, lamps.tunnel_emitters, scene_builder).

- Luminaires: a white Lambertian plane seen with a V(λ)-weighted film, E_v = π L_v: one glowing
  lens (a Lambertian rectangle of luminous flux Φ, L_v = Φ/(πA)) gives the closed-form
  illuminance of a uniform rectangle on a parallel plane, E = L_v Σ± [X/√(1+X²) atan(Y/√(1+X²))
  + Y/√(1+Y²) atan(X/√(1+Y²))] over its corners (X, Y its corner offsets over the height), at
  1 m and 10 m — Φ/(π d²) far away, the inverse square of I₀ = Φ/π; a row of them the sum of
  each, within 2 %.
- Daylight HDR: inside the tunnel by day, the road's luminance is a few cd/m² (CIE 88:2004
  interior zone) and the view through the exit portal 10²–10⁴ times brighter, as real tunnels.
- Labels: the tunnel's pixels are those whose pixel-centre ray meets its walls or roof before the
  road (an independent numpy ray cast), and a car inside has its box where its corners project."""
import numpy as np
import pytest

from workbench.render.film import box_bands
from workbench.render.labels import render_labels
from workbench.render.lamps import LAMP_WAVELENGTHS_NM, luminous_intensity_spectrum
from workbench.render.luminaire_row import luminaire_row_shapes
from workbench.render.params import DaylightParams
from workbench.render.scene_builder import build_scene
from workbench.render.demo_scene import box_mesh
from workbench.scene.city import CLASS_IDS, CameraPose, CityObject, CityRecipe, TunnelParams, generate_city
from workbench.spectra import luminance_from_photons, luminous_efficiency

FLAT = [(300.0, 1.0), (1100.0, 1.0)]
W, H, FOV_DEG = 96, 72, 60.0


def _e_v(mi, lenses: list[dict], camera_z_m: float, spp: int) -> tuple[float, float]:
    """Mean illuminance (lx) on the plane z = 0 around the origin and its standard error."""
    wl = np.arange(360.0, 831.0, 1.0)
    film = {"type": "specfilm", "width": 32, "height": 24, "rfilter": {"type": "box"},
            "component_format": "float32",
            "v": {"type": "spectrum", "value": list(zip(wl.tolist(), luminous_efficiency(wl).tolist()))}}
    scene = {
        "type": "scene", "integrator": {"type": "path", "max_depth": 2},
        "sensor": {"type": "perspective", "fov": 1.0, "film": film, "sampler": {"type": "independent"},
                   "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, camera_z_m], target=[0, 0, 0],
                                                              up=[0, 1, 0])},
        "ground": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale(100.0),
                   "bsdf": {"type": "diffuse", "reflectance": {"type": "spectrum", "value": FLAT}}}}
    scene.update({f"lens_{k}": lens for k, lens in enumerate(lenses)})
    e = np.pi * 683.0 * np.array(mi.render(mi.load_dict(scene), spp=spp, seed=3), dtype=np.float64)[..., 0]
    return float(e.mean()), float(e.std() / np.sqrt(e.size))


def _lenses(centres, kind: str, flux_lm: float, half=(0.2, 0.6)):
    area = 4 * half[0] * half[1]
    radiance = luminous_intensity_spectrum(kind, flux_lm / np.pi, LAMP_WAVELENGTHS_NM) / area
    spectrum = {"type": "spectrum", "value": list(zip(LAMP_WAVELENGTHS_NM.tolist(), radiance.tolist()))}
    return luminaire_row_shapes(np.asarray(centres, float), half, spectrum, 1.0)


def _rect_illuminance(l_v, centre, half, h):
    """Illuminance at the origin under a Lambertian rectangle of luminance l_v facing down."""
    def corner(x, y):
        return x / np.sqrt(1 + x * x) * np.arctan(y / np.sqrt(1 + x * x)) + \
            y / np.sqrt(1 + y * y) * np.arctan(x / np.sqrt(1 + y * y))
    x1, x2 = (centre[0] - half[0]) / h, (centre[0] + half[0]) / h
    y1, y2 = (centre[1] - half[1]) / h, (centre[1] + half[1]) / h
    return l_v / 2 * (corner(x2, y2) - corner(x1, y2) - corner(x2, y1) + corner(x1, y1))


@pytest.mark.parametrize("d", [1.0, 10.0])
def test_one_luminaire_follows_its_flux_and_the_closed_form(mi, d):
    flux, half = 20000.0, (0.2, 0.6)
    got, sem = _e_v(mi, _lenses([[0.0, 0.0, d]], "led", flux, half), d - 0.01, 256)
    want = _rect_illuminance(flux / (np.pi * 4 * half[0] * half[1]), (0.0, 0.0), half, d)
    assert 4 * sem < 0.01 * want
    assert got == pytest.approx(want, rel=0.02)
    if d == 10.0:                                        # far away: the inverse square of I₀ = Φ/π
        assert want == pytest.approx(flux / (np.pi * d ** 2), rel=0.005)


def test_a_row_sums_each_luminaire(mi):
    flux, h, half = 15000.0, 4.9, (0.2, 0.6)
    centres = np.array([[0.4, y, h] for y in np.arange(-60.0, 61.0, 8.0) + 2.5])
    got, sem = _e_v(mi, _lenses(centres, "hps", flux, half), 0.5, 256)
    l_v = flux / (np.pi * 4 * half[0] * half[1])
    want = sum(_rect_illuminance(l_v, c[:2], half, h) for c in centres)
    assert 4 * sem < 0.01 * want
    assert got == pytest.approx(want, rel=0.02)


def _tunnel_city(car: bool):
    recipe = CityRecipe(seed=1, block_size_m=120.0, n_cars=0, n_pedestrians=0, n_buses=0, n_trucks=0,
                        n_trees=0, n_lamps=0, n_benches=0, n_mailboxes=0,
                        tunnel=TunnelParams(street_index=1, length_m=100.0))
    city = generate_city(recipe)
    frame = city.objects[-1].meta["frame"]
    cam = np.array([frame.x_m + 1.75, frame.y_north_m - 40.0, 1.5])
    car_box = (cam + np.array([-0.9, 12.0, -1.5]), cam + np.array([0.9, 16.5, -0.05]))
    if car:
        city.objects.append(CityObject("car", len(city.objects) + 1, [box_mesh(*car_box, "paint_red")]))
    return city, frame, CameraPose(cam, pan_deg=90.0, tilt_deg=0.0, roll_deg=0.0), car_box


def _rays(pose):
    """Unit pixel-centre ray directions (H×W×3) of the pinhole looking along +y (pan 90°)."""
    f_px = (W / 2) / np.tan(np.radians(FOV_DEG / 2))
    u = (np.arange(W) + 0.5 - W / 2) / f_px
    v = (H / 2 - np.arange(H) - 0.5) / f_px
    d = np.stack(np.broadcast_arrays(u[None, :], 1.0, v[:, None]), -1).astype(np.float64)
    return d / np.linalg.norm(d, axis=-1, keepdims=True), f_px


def test_inside_is_dark_and_the_exit_bright_by_day(mi):
    city, frame, pose, _ = _tunnel_city(car=False)
    film = box_bands(380.0, 780.0, 10)
    scene, ids = build_scene(city, pose, FOV_DEG, W, H, film, DaylightParams(sun_elevation_deg=50.0))
    radiance = film.channels_to_radiance(np.array(mi.render(scene, spp=32, seed=5)))
    lum = luminance_from_photons(radiance, film.output_wavelengths_nm)
    labels = render_labels(scene, ids, W, H)
    d, _ = _rays(pose)
    hit_y = pose.position_m[1] + labels.depth_m * d[..., 1]
    road = labels.class_id == CLASS_IDS["road"]
    interior_road = road & (hit_y < frame.y_north_m - 5.0)
    outside = (labels.class_id == 0) | (hit_y > frame.y_north_m + 1.0)
    assert interior_road.sum() > 200 and outside.sum() > 100
    l_in, l_out = lum[interior_road].mean(), lum[outside].mean()
    assert 1.0 < l_in < 20.0, l_in                       # CIE 88 interior zone: a few cd/m²
    assert 1e2 < l_out / l_in < 1e4, (l_in, l_out)


def test_labels_of_the_tunnel_and_a_car_inside_are_exact(mi):
    city, frame, pose, (lo, hi) = _tunnel_city(car=True)
    scene, ids = build_scene(city, pose, FOV_DEG, W, H, box_bands(400.0, 700.0, 2), DaylightParams())
    labels = render_labels(scene, ids, W, H)
    tunnel_id = next(o.instance_id for o in city.objects if o.class_name == "tunnel")
    car_id = city.objects[-1].instance_id
    # the tunnel: walls (above the 0.15 m sidewalks) or roof soffit first, before the road
    d, f_px = _rays(pose)
    o = pose.position_m
    with np.errstate(divide="ignore", invalid="ignore"):
        t_roof = np.where(d[..., 2] > 0, (frame.soffit_z_m - o[2]) / d[..., 2], np.inf)
        x_wall = np.where(d[..., 0] > 0, frame.x_m + frame.half_width_m, frame.x_m - frame.half_width_m)
        t_wall = np.where(d[..., 0] != 0, (x_wall - o[0]) / d[..., 0], np.inf)
        t_floor = np.where(d[..., 2] < 0, -o[2] / d[..., 2], np.inf)
    t = np.minimum(t_roof, t_wall)
    z_hit = o[2] + t * d[..., 2]
    y_hit = o[1] + t * d[..., 1]
    oracle = (t < t_floor) & (y_hit <= frame.y_north_m) & ((t == t_roof) | (z_hit >= 0.15))
    got = labels.instance_id == tunnel_id
    car = labels.instance_id == car_id
    mismatch = (got != oracle) & ~car
    assert mismatch.mean() < 0.01, mismatch.sum()
    # the car: its box where its corners project (± 1 px), nothing in front of it
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]) - o
    u = W / 2 + f_px * corners[:, 0] / corners[:, 1]
    v = H / 2 - f_px * corners[:, 2] / corners[:, 1]
    want = (u.min(), v.min(), u.max() - u.min(), v.max() - v.min())
    obj = next(ob for ob in labels.objects if ob.instance_id == car_id)
    assert obj.class_name == "car" and obj.bbox_xywh == obj.amodal_bbox_xywh
    np.testing.assert_allclose(obj.bbox_xywh, want, atol=1.0)


def test_the_row_registry_keeps_only_the_newest_rows(mi):
    """Each distinct row is registered for its scene's loading; a long data set of tunnel cities
    keeps at most MAX_ROWS of them, and the newest always loads."""
    from workbench.render import luminaire_row
    for k in range(luminaire_row.MAX_ROWS + 5):
        lenses = _lenses([(0.0, float(k), 5.0)], "led", 1000.0)
    assert len(luminaire_row._ROWS) == luminaire_row.MAX_ROWS
    assert mi.load_dict(lenses[0]) is not None

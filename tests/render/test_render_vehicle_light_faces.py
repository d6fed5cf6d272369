"""Vehicle lights that read as lights at night (render/lamp_heads.vehicle_light_face_shape).

Head- and tail-lights are Mitsuba spots, which a camera cannot see: the tail-light of a car ahead
read 0.02 cd/m² for a lens shedding 10 cd. Now each has a face over its lens whose radiance is the
spot's own intensity toward the viewer over its area:
- Seen: r² Σ L_v Ω_pixel over the face holds the closed-form intensity toward the camera — 10 cd
  in a tail-light's beam, and the SAE J1383 low beam (low_beam.low_beam_cd) from two directions
  of a head-light, one on the steep cut-off — within 3 %.
- Adds no light: the ground 8 m ahead keeps the head-light's closed-form illuminance
  E = I cos θ / r² with the face (2 %).
- In a city at night the faces carry their vehicle's label; parked cars and daylight have none."""
import numpy as np
import pytest

from workbench.render.lamp_heads import vehicle_light_face_shape
from workbench.render.lamps import headlight_emitter, spot_emitter
from workbench.render.low_beam import direction_angles_deg, low_beam_cd
from workbench.render.spot_pattern import frame

HEIGHT_M = 0.7
# a lens box 0.3 m across, 0.15 m high, its front at x = 2 m; the spot 2 cm ahead of it, facing +x
LENS = np.array([[x, y, z] for x in (1.95, 2.0) for y in (-0.15, 0.15) for z in (HEIGHT_M - 0.075, HEIGHT_M + 0.075)])
SPOT_AT = [2.02, 0.0, HEIGHT_M]


def _v_film(w: int, h: int) -> dict:
    from workbench.spectra import luminous_efficiency
    wl = np.arange(360.0, 831.0, 1.0)
    return {"type": "specfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "component_format": "float32",
            "v": {"type": "spectrum", "value": list(zip(wl.tolist(), luminous_efficiency(wl).tolist()))}}


def _scene(mi, spot: dict, face: bool, origin, target, fov_deg: float, n: int, up=(0, 0, 1)) -> dict:
    scene = {"type": "scene", "integrator": {"type": "path", "max_depth": 3},
             "sensor": {"type": "perspective", "fov": fov_deg, "film": _v_film(n, n),
                        "sampler": {"type": "independent"},
                        "to_world": mi.ScalarTransform4f().look_at(origin=list(origin), target=list(target),
                                                                   up=list(up))},
             "ground": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale(100.0),
                        "bsdf": {"type": "diffuse", "reflectance": {"type": "spectrum", "value": 1.0}}},
             "spot": spot}
    if face:
        scene["face"] = vehicle_light_face_shape(LENS, spot, "test:" + ("head" if "texture" in spot else "tail"), 0)
    return scene


def _seen_cd(mi, spot: dict, camera) -> float:
    """r² Σ L_v Ω_pixel over the face's pixels, the camera aimed at the face from `camera`."""
    fov, n = 3.0, 64
    target = [2.002, 0.0, HEIGHT_M]
    img = np.array(mi.render(mi.load_dict(_scene(mi, spot, True, camera, target, fov, n)), spp=256, seed=2),
                   dtype=np.float64)[..., 0]
    face = img > 50 * np.median(img) + 1e-12
    assert face.sum() > 20
    pixel_sr = (2 * np.tan(np.radians(fov / 2)) / n) ** 2
    r = np.asarray(camera) - np.asarray(target)
    return 683.0 * img[face].sum() * pixel_sr * float(r @ r)


def test_a_tail_light_face_shows_its_intensity(mi):
    spot = spot_emitter(SPOT_AT, [1.0, 0.0, 0.0], "led_red", 10.0, cutoff_deg=60.0, beam_deg=20.0)
    assert _seen_cd(mi, spot, [14.0, 2.0, 1.5]) == pytest.approx(10.0, rel=0.03)      # 10° off the axis


@pytest.mark.parametrize("camera", [[16.0, -0.5, 0.3], [16.0, 0.4, HEIGHT_M + 0.05]])
def test_a_head_light_face_shows_the_low_beam(mi, camera):
    """Below the cut-off, right of the axis (~2600 cd), and on the cut-off itself (~300 cd)."""
    spot = headlight_emitter(SPOT_AT, [1.0, 0.0, 0.0], "led", 20000.0)
    origin, left, up, axis = frame(spot)
    d = np.asarray(camera) - origin
    want = float(low_beam_cd(*direction_angles_deg(d @ left, d @ up, d @ axis), peak_cd=20000.0))
    assert _seen_cd(mi, spot, camera) == pytest.approx(want, rel=0.03)


def test_a_vehicle_light_face_adds_no_light(mi):
    spot = headlight_emitter(SPOT_AT, [1.0, 0.0, 0.0], "led", 20000.0)
    spot["sampling_weight"] = 1.0

    def e_v(face: bool):
        scene = mi.load_dict(_scene(mi, spot, face, [10.0, 0.3, 0.5], [10.0, 0.3, 0.0], 1.0, 24, up=(0, 1, 0)))
        e = np.pi * 683.0 * np.array(mi.render(scene, spp=64, seed=3), dtype=np.float64)[..., 0]
        return e.mean(), e.std() / np.sqrt(e.size)
    origin, left, up, axis = frame(spot)
    d = np.array([10.0, 0.3, 0.0]) - origin
    r2 = float(d @ d)
    want = float(low_beam_cd(*direction_angles_deg(d @ left, d @ up, d @ axis), peak_cd=20000.0)) * HEIGHT_M / r2 ** 1.5
    for face in (False, True):                   # E = I cos θ / r² on the ground 8 m ahead, with the face or not
        got, sem = e_v(face)
        assert 4 * sem < 0.01 * want
        assert got == pytest.approx(want, rel=0.02), face


def test_vehicle_light_faces_carry_their_vehicles_labels_at_night_only(mi):
    from workbench.render.film import box_bands
    from workbench.render.params import DaylightParams, NightParams, WorldParams
    from workbench.render.scene_builder import build_scene
    from workbench.scene.city import CameraPose, CityRecipe, generate_city

    city = generate_city(CityRecipe(seed=3, n_cars=6, n_pedestrians=0, n_buses=0, n_trucks=0, n_trees=0, n_lamps=0))
    moving = {o.instance_id: o.class_name for o in city.objects
              if o.class_name in ("car", "bus", "truck") and not o.meta.get("parked")}
    pose = CameraPose(np.array([50.0, 50.0, 1.5]), pan_deg=0.0, tilt_deg=0.0, roll_deg=0.0)
    film = box_bands(400.0, 700.0, 2)
    _, ids = build_scene(city, pose, 60.0, 16, 12, film, DaylightParams(), world=WorldParams(lighting="night"))
    faces = {k: v for k, v in ids.items() if k.startswith("face_")}
    assert moving and len(faces) == 4 * len(moving)              # two head- and two tail-lights each
    assert {(v.class_name, v.instance_id) for v in faces.values()} == set((c, i) for i, c in moving.items())
    dark = WorldParams(lighting="night", night=NightParams(vehicle_lights=False))
    assert not any(k.startswith("face_") for k in build_scene(city, pose, 60.0, 16, 12, film, DaylightParams(),
                                                              world=dark)[1])
    assert not any(k.startswith("face_") for k in build_scene(city, pose, 60.0, 16, 12, film, DaylightParams())[1])

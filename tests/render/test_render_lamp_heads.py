"""Street-lamp heads that read as lamps at night (render/lamp_heads.py; issue 33 item 3).

- Seen: a lamp's face, rendered from the street with a V(λ)-weighted film, holds the point
  emitter's luminous intensity Φ/(2π) toward the camera: r² Σ L_v Ω_pixel, within 3 %.
- Adds no light: a white Lambertian plane under the lamp, with the face and two bounces, keeps
  the closed-form illuminance of the point emitter alone, E = I cos θ / r² (I = Φ/(2π)), within
  2 % (a face that emitted into the scene would add about as much again).
- In a city at night the faces are in the scene with the lamps' labels; by day they are absent."""
import numpy as np
import pytest

from workbench.render.lamp_heads import lamp_face_shape, lens_rectangle
from workbench.render.lamps import LAMP_WAVELENGTHS_NM, luminous_intensity_spectrum, street_lamp_emitter
from workbench.spectra import luminous_efficiency

FLUX_LM, HEIGHT_M = 15000.0, 6.0
# the lamp asset's lens: 0.5 m × 0.24 m, turned 30° about the vertical
_ANGLE = np.radians(30.0)
_ROT = np.array([[np.cos(_ANGLE), -np.sin(_ANGLE)], [np.sin(_ANGLE), np.cos(_ANGLE)]])
LENS = np.column_stack([np.array([[-0.25, -0.12], [-0.25, 0.12], [0.25, 0.12], [0.25, -0.12]]) @ _ROT.T,
                        np.full(4, HEIGHT_M)])


def _v_film(w: int, h: int) -> dict:
    wl = np.arange(360.0, 831.0, 1.0)
    return {"type": "specfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "component_format": "float32",
            "v": {"type": "spectrum", "value": list(zip(wl.tolist(), luminous_efficiency(wl).tolist()))}}


def _lamp(face: bool) -> dict:
    intensity = luminous_intensity_spectrum("hps", FLUX_LM / (2 * np.pi), LAMP_WAVELENGTHS_NM)
    spectrum = {"type": "spectrum", "value": list(zip(LAMP_WAVELENGTHS_NM.tolist(), intensity.tolist()))}
    out = {"lamp": street_lamp_emitter([0.0, 0.0, HEIGHT_M - 0.015], "hps", FLUX_LM)}
    if face:
        out["face"] = lamp_face_shape(LENS, spectrum, 89.9)
    return out


def _scene(mi, face: bool, origin, target, fov_deg: float, w: int, h: int, up=(0, 0, 1)) -> dict:
    return {"type": "scene", "integrator": {"type": "path", "max_depth": 3},
            "sensor": {"type": "perspective", "fov": fov_deg, "film": _v_film(w, h),
                       "sampler": {"type": "independent"},
                       "to_world": mi.ScalarTransform4f().look_at(origin=origin, target=target, up=list(up))},
            "ground": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale(100.0),
                       "bsdf": {"type": "diffuse", "reflectance": {"type": "spectrum", "value": 1.0}}},
            **_lamp(face)}


def test_the_lens_rectangle_is_found_in_any_vertex_order():
    centre, axis, half = lens_rectangle(LENS[[2, 0, 3, 1]])
    np.testing.assert_allclose(centre, [0.0, 0.0, HEIGHT_M], atol=1e-12)
    assert abs(axis[:2] @ [np.cos(_ANGLE), np.sin(_ANGLE)]) == pytest.approx(1.0)
    np.testing.assert_allclose(half, (0.25, 0.12))


def test_a_lamp_face_shows_the_point_emitters_intensity(mi):
    d = np.array([20.0, 5.0])                      # the camera 20.6 m away on the street, 1.5 m up
    origin = [float(d[0]), float(d[1]), 1.5]
    fov, n = 3.0, 96
    img = np.array(mi.render(mi.load_dict(_scene(mi, True, origin, [0.0, 0.0, HEIGHT_M], fov, n, n)), spp=64,
                             seed=2), dtype=np.float64)[..., 0]
    pixel_sr = (2 * np.tan(np.radians(fov / 2)) / n) ** 2
    head = img > 10 * np.median(img)
    r2 = d @ d + (HEIGHT_M - 0.015 - FACE_DROP - 1.5) ** 2
    got = 683.0 * img[head].sum() * pixel_sr * r2
    assert head.sum() > 20
    assert got == pytest.approx(FLUX_LM / (2 * np.pi), rel=0.03)


FACE_DROP = 0.002


@pytest.mark.parametrize("x_m", [0.0, 3.0])
def test_a_lamp_face_adds_no_light_to_the_street(mi, x_m):
    def e_v(face: bool):
        scene = mi.load_dict(_scene(mi, face, [x_m, 0.0, 0.5], [x_m, 0.0, 0.0], 1.0, 32, 24, up=(0, 1, 0)))
        e = np.pi * 683.0 * np.array(mi.render(scene, spp=64, seed=3), dtype=np.float64)[..., 0]
        return e.mean(), e.std() / np.sqrt(e.size)
    h = HEIGHT_M - 0.015
    r2 = x_m ** 2 + h ** 2
    want = FLUX_LM / (2 * np.pi) * (h / np.sqrt(r2)) / r2
    for face in (False, True):
        got, sem = e_v(face)
        assert 4 * sem < 0.01 * want
        assert got == pytest.approx(want, rel=0.02), face


def _night_frame(monkeypatch, faces: bool):
    """Frame 1 of city_night (a lamp 32 m ahead) at 160×120, 16 spp: (V-weighted irradiance, class ids)."""
    from workbench.datasets.contact_sheet import sheet_project
    from workbench.project import load_project
    from workbench.render import scene_builder
    from workbench.render.city_frame import project_frame_seeds, render_city_frame
    if not faces:
        monkeypatch.setattr(scene_builder, "lamp_faces", lambda city, night: {})
    project = sheet_project(load_project("city_night"), 160, 120, 16)
    data = render_city_frame(project, project_frame_seeds(project, 1))
    v = (data.irradiance_photons * luminous_efficiency(np.asarray(data.wavelengths_nm))).sum(-1)
    monkeypatch.undo()
    return v, data.labels.class_id


def test_lamp_heads_glow_in_a_night_city_and_light_nothing_else(mi, monkeypatch):
    """The brightest pixels of a night street are now its lamp heads (before: light on the ground
    under dark heads); every other pixel is as it was, to 0.1 %: the faces add no light."""
    from workbench.scene.city import CLASS_IDS
    with_faces, classes = _night_frame(monkeypatch, True)
    without, classes_before = _night_frame(monkeypatch, False)
    lamp = classes == CLASS_IDS["lamp"]
    road = classes == CLASS_IDS["road"]
    assert lamp.any() and road.any()
    assert with_faces[lamp].max() > 1e3 * with_faces[road].mean()
    assert without[lamp].max() < 1e2 * without[road].mean()
    assert with_faces.max() == with_faces[lamp].max()
    rest = ~lamp & (classes_before == classes)
    assert with_faces[rest].mean() == pytest.approx(without[rest].mean(), rel=1e-3)


def test_the_faces_are_in_a_night_scene_with_their_lamps_labels_and_absent_by_day(mi):
    from workbench.render.film import box_bands
    from workbench.render.params import DaylightParams, WorldParams
    from workbench.render.scene_builder import build_scene
    from workbench.scene.city import CameraPose, CityRecipe, generate_city
    city = generate_city(CityRecipe(seed=1, n_cars=0, n_pedestrians=0, n_buses=0, n_trucks=0, n_trees=0, n_lamps=4,
                                    n_benches=0, n_mailboxes=0))
    lamps = {o.instance_id for o in city.objects if o.class_name == "lamp"}
    pose = CameraPose(np.array([50.0, 50.0, 1.5]), pan_deg=0.0, tilt_deg=0.0, roll_deg=0.0)
    film = box_bands(400.0, 700.0, 2)
    _, night_ids = build_scene(city, pose, 60.0, 16, 12, film, DaylightParams(), world=WorldParams(lighting="night"))
    faces = {k: v for k, v in night_ids.items() if k.startswith("lamp_face_")}
    assert {v.instance_id for v in faces.values()} == lamps and {v.class_name for v in faces.values()} == {"lamp"}
    _, day_ids = build_scene(city, pose, 60.0, 16, 12, film, DaylightParams())
    assert not any(k.startswith("lamp_face_") for k in day_ids)

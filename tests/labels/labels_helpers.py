"""Shared by the tests/labels tests: a tiny, real frame renderer (module-level, so that
spawned worker processes can import it)."""
import numpy as np

from workbench.render.city_frame import FrameData

W, H = 32, 24


def tiny_renderer(project, seeds):
    """A real but tiny frame: the demo city with one car moved by the arrangement seed, the camera
    panned by the pose seed, 2 spp, 4 bands; 'irradiance' is the radiance (no optics here)."""
    from workbench.render.demo_scene import demo_city, demo_pose
    from workbench.render.film import box_bands
    from workbench.render.labels import render_labels
    from workbench.render.params import DaylightParams
    from workbench.render.scene_builder import build_scene
    from workbench.render.variants import import_mitsuba

    mi = import_mitsuba("llvm_ad_spectral")
    city = demo_city()
    shift = np.random.default_rng(seeds.arrangement).uniform(-2.0, 2.0)
    car = next(o for o in city.objects if o.instance_id == 3)
    for m in car.meshes:
        m.vertices = m.vertices + np.array([0.0, shift, 0.0])
    pose = demo_pose()
    pose.pan_deg = float(np.random.default_rng(seeds.pose).uniform(-5.0, 5.0))
    film = box_bands(400.0, 700.0, 4)
    scene, table = build_scene(city, pose, 50.0, W, H, film, DaylightParams(), max_depth=2)
    channels = np.array(mi.render(scene, spp=2, seed=seeds.render), dtype=np.float64)
    labels = render_labels(scene, table, W, H)
    return FrameData(film.channels_to_radiance(channels).astype(np.float32),
                     film.output_wavelengths_nm, labels, {"shift_m": shift})


def session_renderer(project, seeds, session=None):
    """A stand-in frame that records which session made it (a number given to each new session)
    and how many frames that session had made before."""
    from itertools import count

    from workbench.render.labels import Labels
    global _SESSIONS
    _SESSIONS = globals().get("_SESSIONS") or count()
    if not hasattr(session, "test_id"):
        session.test_id, session.test_frames = next(_SESSIONS), 0
    made = session.test_frames
    session.test_frames += 1
    depth = np.ones((H, W), np.float32)
    labels = Labels(depth, depth, np.zeros((H, W), np.int32), np.zeros((H, W), np.int32), [], {})
    return FrameData(np.ones((H, W, 2), np.float32), np.array([500.0, 600.0]), labels,
                     {"session": session.test_id, "frame_in_session": made})

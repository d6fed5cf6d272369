"""One city frame: seeds → city arrangement and camera pose → Mitsuba render (pinhole radiance or,
for the full lens model, sensor irradiance) with its label pass → sensor-plane irradiance.

Frame i is a pure function of the project and i: its seeds (city arrangement, camera pose, render
noise) come from numpy's SeedSequence([project.seed, DATASET_SEED_TAG, i]). The pipeline renders
frame 0 as its scene stage; data sets (dataset.py) render many.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from workbench.render.labels import Labels

DATASET_SEED_TAG = 0x6461_7461       # separates data-set seeds from other uses of the project seed


@dataclass(frozen=True)
class FrameSeeds:
    """The seeds of frame `index`: city arrangement, camera pose and Mitsuba render noise."""

    index: int
    arrangement: int
    pose: int
    render: int


def frame_seeds(project_seed: int, index: int) -> FrameSeeds:
    """Seeds of frame `index`, derived from the project seed (independent streams per frame)."""
    if index < 0:
        raise ValueError(f"frame index must be ≥ 0, got {index}")
    words = np.random.SeedSequence([int(project_seed), DATASET_SEED_TAG, int(index)]).generate_state(3)
    return FrameSeeds(int(index), int(words[0] >> 1), int(words[1] >> 1), int(words[2]))


@dataclass
class FrameData:
    """One rendered frame: sensor-plane irradiance (photons/s/m²/nm, H×W×Nλ) and its labels."""

    irradiance_photons: np.ndarray
    wavelengths_nm: np.ndarray
    labels: Labels
    meta: dict = field(default_factory=dict)


def frame_optical_image(data: FrameData):
    """A stored frame as the OpticalImage the sensor stage takes (needs the optics fields that
    render_city_frame records in meta: sample_spacing_m, focal_length_m, f_number)."""
    from workbench.optics.types import OpticalImage
    missing = [k for k in ("sample_spacing_m", "focal_length_m", "f_number") if k not in data.meta]
    if missing:
        raise ValueError(f"frame meta lacks {missing}: it was not made by render_city_frame")
    return OpticalImage(data.irradiance_photons, np.asarray(data.wavelengths_nm, np.float64),
                        float(data.meta["sample_spacing_m"]), float(data.meta["focal_length_m"]),
                        float(data.meta["f_number"]), depth_m=data.labels.depth_m,
                        meta={**{k: v for k, v in data.meta.get("render", {}).items() if k in FILM_META_KEYS},
                              "frame": data.meta})


def uses_full_lens_model(optics) -> bool:
    """True when city frames render through the real lens inside Mitsuba (the full model):
    optics.model 'raytrace' with a lens_file."""
    return optics.model == "raytrace" and optics.lens_file is not None


@dataclass
class CityRender:
    """One rendered city frame before the sensor: the render (spectral radiance through a pinhole,
    or sensor irradiance through the full lens camera), its labels, and how it was made."""

    scene: object                 # workbench.scene.types.Scene
    labels: object                # workbench.render.labels.Labels
    camera: object | None         # FullModelCamera when the film holds lens irradiance
    meta: dict


# Scene meta entries the sensor needs to read a render whose film is not a spectrum.
FILM_META_KEYS = ("representation", "channel_names", "channel_integrals_nm", "channel_centroids_nm")


def render_city_scene(project, seeds: FrameSeeds, on_progress: Callable | None = None) -> CityRender:
    """Render frame `seeds.index` of a city project, with the label pass cast through the same
    Mitsuba scene.

    The city's streets and buildings come from project.city; its arrangement, the camera pose
    and the render noise from `seeds`. Resolution = sensor rows × cols × scene.oversample.
    Pinhole path: a pinhole radiance render (field of view scene.fov_deg, or the sensor behind
    the optics: pipeline.camera_hfov_deg); city_optical_image then applies the optics level.
    The visible sun disc is composited where camera rays reach the sky (render/sun_disc.py,
    render.daylight.sun_visible; meta['sun_disc']); not on the full-model path below.
    Full model (optics.model 'raytrace' with a lens_file, uses_full_lens_model): Mitsuba traces
    every camera ray through the lens (render.lens_camera, weight 'irradiance'), so the film holds
    sensor irradiance. The lens is prepared as formation/ prepares it and focused on
    optics.focus_distance_m or else scene.distance_m (the distance camera_hfov_deg focuses on);
    the sensor is cols × pixel pitch wide (or spans scene.fov_deg at the image distance), so the
    sample spacing is pixel pitch / oversample. Labels are cast through the lens camera (each
    pixel's ray through the centre of its exit-pupil box), so boxes follow the lens's distortion.
    render.shot_noise_ratio is resolved here: a pilot render through the optics and sensor gives
    the mean electrons N_e of the exposure, and the target error is ratio/√N_e."""
    from workbench.jobs import run_job
    from workbench.pipeline import camera_hfov_deg
    from workbench.render.labels import render_labels
    from workbench.render.scene_builder import build_scene, pinhole_sensor
    from workbench.render.spectral import film_for, render_loaded
    from workbench.render.variants import select_variant
    from workbench.scene.city import generate_city, sample_camera_poses
    from workbench.scene.city.recipe import CityRecipe, PoseParams
    from workbench.sensor.cfa import channel_qe

    if project.scene.kind != "city":
        raise ValueError(f"scene.kind is '{project.scene.kind}'; rendering a frame needs scene.kind 'city'")
    recipe = (project.city or CityRecipe()).model_copy(update={"arrangement": seeds.arrangement})
    city = generate_city(recipe)
    pose = sample_camera_poses(city, project.pose or PoseParams(), 1, seeds.pose)[0]
    over = project.scene.oversample
    width, height = project.sensor.cols * over, project.sensor.rows * over
    variant = select_variant(project.render.variant)
    qe_wl = np.arange(350.0, 1000.1, 5.0)
    film = film_for(project.render, (qe_wl, np.asarray(channel_qe(project.sensor, qe_wl)).T))
    optics, camera, lens_sensor = project.optics, None, None
    if uses_full_lens_model(optics):
        from workbench.optics.formation.full_model import full_model_camera
        from workbench.render.lens_camera import lens_sensor_dict
        if project.scene.fov_deg is not None:
            camera = full_model_camera(optics, project.scene.distance_m, fov_deg=project.scene.fov_deg)
        else:
            camera = full_model_camera(optics, project.scene.distance_m,
                                       sensor_width_mm=project.sensor.cols * project.sensor.pixel_pitch_um * 1e-3)
        fov = camera.fov_deg
        lens_sensor = lens_sensor_dict(camera.lens, {"width": width, "height": height},
                                       pinhole_sensor(pose, fov)["to_world"], camera.sensor_width_mm,
                                       weight="irradiance")
    else:
        fov = project.scene.fov_deg or camera_hfov_deg(project)
    mi_scene, id_table = build_scene(city, pose, fov, width, height, film, project.render.daylight,
                                     lens_sensor, max_depth=project.render.max_depth, world=project.render.world)
    labels = render_labels(mi_scene, id_table, width, height)
    params = project.render.updated(seed=seeds.render)
    meta = {"variant": variant, "fov_deg": fov, "city_seed": recipe.seed, "arrangement": recipe.arrangement,
            "pose": {"position_m": np.asarray(pose.position_m).tolist(), "pan_deg": pose.pan_deg,
                     "tilt_deg": pose.tilt_deg, "roll_deg": pose.roll_deg,
                     "meta": getattr(pose, "meta", {})}}
    night = project.render.world.lighting == "night"
    if camera is None and not night:    # the disc the directional sun cannot show
        from workbench.render.sun_disc import sun_disc
        disc = sun_disc(film, pose, fov, width, height, project.render.daylight, mi_scene=mi_scene)
        meta["sun_disc"] = disc.meta
    else:
        disc = None
        meta["sun_disc"] = {"status": "not composited: " + ("night" if night else
                                                             "the full lens model bends the camera rays")}

    def with_sun(scene):
        if disc is not None:
            scene.radiance_photons = disc.add_to(scene.radiance_photons)
        return scene

    if params.shot_noise_ratio is not None:
        pilot = with_sun(run_job(render_loaded(mi_scene, film, params.updated(spp=params.pilot_spp, shot_noise_ratio=None),
                                             fov_deg=fov, name=f"frame {seeds.index} pilot")))
        pilot.depth_m = labels.depth_m
        target = sensor_matched_error(project, CityRender(pilot, labels, camera, meta), params.shot_noise_ratio)
        meta["shot_noise_target_rel_error"] = target
        params = params.updated(shot_noise_ratio=None, target_rel_error=target)
    scene = with_sun(run_job(render_loaded(mi_scene, film, params, fov_deg=fov, name=f"frame {seeds.index}"),
                           on_progress))
    scene.depth_m = labels.depth_m
    meta["spp"] = scene.meta.get("spp")
    meta["render"] = scene.meta
    return CityRender(scene, labels, camera, meta)


def sensor_matched_error(project, render: CityRender, shot_noise_ratio: float) -> float:
    """Relative render error that is `shot_noise_ratio` × the photon shot noise 1/√N_e, with N_e
    the mean electrons per pixel of the project's sensor at its exposure on this render."""
    from workbench.sensor import irradiance_to_signal_rate, resolve_exposure
    rate = irradiance_to_signal_rate(city_optical_image(render, project), project.sensor)
    exposure_s = float(np.mean(resolve_exposure(rate, project.sensor)))
    mean_e = float(np.mean(rate, dtype=np.float64)) * exposure_s
    if not mean_e > 0:
        raise ValueError("render.shot_noise_ratio: the pilot render collects no electrons at this exposure; "
                         "give spp or target_rel_error instead")
    return float(min(shot_noise_ratio / np.sqrt(mean_e), 0.99))


def city_optical_image(render: CityRender, project):
    """Sensor-plane irradiance of a city render: the project's optics level on the pinhole
    radiance, or the full lens camera's film as it is; then scene.adjust_illuminance_lux."""
    from workbench.pipeline import form_optical_image, scale_to_mean_illuminance
    film_meta = {k: render.scene.meta[k] for k in FILM_META_KEYS if k in render.scene.meta}
    if render.camera is None:
        oi = form_optical_image(render.scene, project)
        oi.meta.update(film_meta)
        return oi
    from workbench.optics.formation.full_model import full_model_optical_image
    oi = full_model_optical_image(render.scene.radiance_photons, render.scene.wavelengths_nm, render.camera,
                                  project.optics, depth_m=render.labels.depth_m, meta=film_meta)
    return scale_to_mean_illuminance(oi, project.scene.adjust_illuminance_lux)


def render_city_frame(project, seeds: FrameSeeds, on_progress: Callable | None = None) -> FrameData:
    """Render frame `seeds.index` of a city project to sensor irradiance with its labels
    (render_city_scene, then city_optical_image)."""
    render = render_city_scene(project, seeds, on_progress)
    oi = city_optical_image(render, project)
    meta = {**render.meta, "optics_model": oi.meta.get("model", project.optics.model),
            "sample_spacing_m": oi.sample_spacing_m, "focal_length_m": oi.focal_length_m,
            "f_number": oi.f_number}
    return FrameData(oi.irradiance_photons, oi.wavelengths_nm, render.labels, meta)

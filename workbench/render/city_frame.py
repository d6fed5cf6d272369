"""One city frame: seeds → city arrangement and camera pose → Mitsuba render (pinhole radiance or,
for the full lens model, sensor irradiance) with its label pass → sensor-plane irradiance.

Frame i is a pure function of the project and i: its seeds (city arrangement, camera pose, render
noise) come from numpy's SeedSequence([project.seed, DATASET_SEED_TAG, i]). The pipeline renders
frame 0 as its scene stage; data sets (dataset.py) render many.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Callable

import numpy as np

from workbench.errors import InvalidValueError, StageError
from workbench.jobs import Job
from workbench.render.labels import Labels

DATASET_SEED_TAG = 0x6461_7461       # separates data-set seeds from other uses of the project seed


@dataclass(frozen=True)
class FrameSeeds:
    """The seeds of frame `index`: city arrangement, camera pose and Mitsuba render noise; `city`
    numbers the frame's arrangement group (frames city·K … city·K + K − 1 share an arrangement,
    K = pose.poses_per_arrangement)."""

    index: int
    arrangement: int
    pose: int
    render: int
    city: int = -1

    def __post_init__(self) -> None:
        if self.city < 0:                       # one arrangement per frame
            object.__setattr__(self, "city", self.index)


def _seed_words(project_seed: int, index: int) -> np.ndarray:
    return np.random.SeedSequence([int(project_seed), DATASET_SEED_TAG, int(index)]).generate_state(3)


def frame_seeds(project_seed: int, index: int, poses_per_arrangement: int = 1) -> FrameSeeds:
    """Seeds of frame `index`, derived from the project seed (independent streams per frame). With
    K = poses_per_arrangement > 1, frame i takes the arrangement of frame K·⌊i/K⌋ (its own pose and
    render noise): K = 1 gives every frame its own arrangement, as before the option existed."""
    if index < 0:
        raise InvalidValueError(f"frame index must be ≥ 0, got {index}")
    if poses_per_arrangement < 1:
        raise InvalidValueError(f"poses_per_arrangement must be ≥ 1, got {poses_per_arrangement}")
    city = int(index) // int(poses_per_arrangement)
    words = _seed_words(project_seed, index)
    arrangement = words[0] if poses_per_arrangement == 1 else _seed_words(project_seed, city * poses_per_arrangement)[0]
    return FrameSeeds(int(index), int(arrangement >> 1), int(words[1] >> 1), int(words[2]), city)


def project_frame_seeds(project, index: int) -> FrameSeeds:
    """frame_seeds of frame `index` of a project (its seed and pose.poses_per_arrangement)."""
    return frame_seeds(project.seed, index, project.pose.poses_per_arrangement if project.pose is not None else 1)


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
        raise InvalidValueError(f"frame meta lacks {missing}: it was not made by render_city_frame")
    return OpticalImage(data.irradiance_photons, np.asarray(data.wavelengths_nm, np.float64),
                        float(data.meta["sample_spacing_m"]), float(data.meta["focal_length_m"]),
                        float(data.meta["f_number"]), depth_m=data.labels.depth_m,
                        meta={**{k: v for k, v in data.meta.get("render", {}).items() if k in FILM_META_KEYS},
                              "frame": data.meta})


def uses_full_lens_model(optics) -> bool:
    """True when city frames render through the real lens inside Mitsuba (the full model):
    optics.model 'raytrace' with a lens_file."""
    return optics.model == "raytrace" and optics.lens_file is not None


@dataclass(frozen=True)
class CitySceneInputs:
    """All a city frame's render reads (so it is the scene stage's cache key): the project seed,
    scene, city, pose and render sections (a spectral film's wavelength range resolved), the pixel
    response (all of it for a film in the sensor's channels, only the pixel grid for a spectral
    film), the camera geometry; the optics only when the lens is traced inside
    Mitsuba (full model) or render.shot_noise_ratio needs a pilot through the optics, and the
    sensor only for shot_noise_ratio (its exposure)."""

    seed: int
    scene: object                 # SceneParams
    city: object                  # CityRecipe
    pose: object                  # PoseParams
    render: object                # RenderParams
    pixels: object                # PixelResponseParams
    camera: object                # CameraGeometry
    optics: object | None = None  # OpticsParams
    sensor: object | None = None  # SensorParams


@dataclass(frozen=True)
class CityFrameInputs:
    """All a stored frame (render_city_frame) reads: the render's inputs, then the optics level
    and the mean-illuminance adjustment applied to it."""

    render: CitySceneInputs
    optics: object                # OpticsParams
    adjust_illuminance_lux: float | None


def city_scene_inputs(project) -> CitySceneInputs:
    """What rendering a city frame of `project` reads (CitySceneInputs). A film in the sensor's
    own channels reads the whole pixel response; a spectral film ('bands', 'basis') only the
    wavelength range, written into the render section here when it follows the sensor's QE, so a
    CFA, filter or fill-factor edit that keeps that range keeps the render (the sensor stage
    integrates the spectrum)."""
    from workbench.scene.city.recipe import CityRecipe, PoseParams
    from workbench.stages.geometry import project_geometry
    pilot = project.render.shot_noise_ratio is not None
    render, pixels = project.render, project.sensor.pixel_response
    if render.representation != "sensor" and not pilot:
        if render.wavelength_min_nm is None:
            lo, hi = sensor_film_range_nm(pixels)
            render = render.updated(wavelength_min_nm=lo, wavelength_max_nm=hi)
        pixels = type(pixels)(rows=pixels.rows, cols=pixels.cols, pixel_pitch_um=pixels.pixel_pitch_um)
    return CitySceneInputs(project.seed, project.scene, project.city or CityRecipe(), project.pose or PoseParams(),
                           render, pixels, project_geometry(project),
                           project.optics if pilot or uses_full_lens_model(project.optics) else None,
                           project.sensor if pilot else None)


def sensor_film_range_nm(pixels) -> tuple[float, float]:
    """The wavelength range (nm) a spectral film covers when the render does not set one: where
    any channel of the sensor responds (film.sensor_wavelength_range of its QE)."""
    from workbench.render.film import sensor_wavelength_range
    from workbench.sensor.cfa import SENSOR_SPECTRAL_GRID_NM, channel_qe
    return sensor_wavelength_range(SENSOR_SPECTRAL_GRID_NM, np.asarray(channel_qe(pixels, SENSOR_SPECTRAL_GRID_NM)).T)


def city_frame_inputs(project) -> CityFrameInputs:
    """What a stored frame of `project` reads (CityFrameInputs): its data-set fingerprint."""
    return CityFrameInputs(city_scene_inputs(project), project.optics, project.scene.adjust_illuminance_lux)


INPUT_NAMES = {"seed": "seed", "scene": "scene", "city": "city", "pose": "pose", "render": "render",
               "pixels": "sensor pixel response", "camera": "camera geometry", "optics": "optics",
               "sensor": "sensor", "adjust_illuminance_lux": "scene.adjust_illuminance_lux"}


def frame_input_differences(project, other) -> list[str]:
    """What differs between the frame inputs of two projects (empty: they make the same frames)."""
    a, b = city_frame_inputs(project), city_frame_inputs(other)
    names = [f.name for f in fields(CitySceneInputs) if getattr(a.render, f.name) != getattr(b.render, f.name)]
    names += [n for n in ("optics", "adjust_illuminance_lux") if getattr(a, n) != getattr(b, n) and n not in names]
    return [INPUT_NAMES[n] for n in names]


@dataclass
class CityRender:
    """One rendered city frame before the sensor: the render (spectral radiance through a pinhole,
    or sensor irradiance through the full lens camera), its labels, and how it was made."""

    scene: object                 # workbench.scene.types.Scene
    labels: object                # workbench.render.labels.Labels
    camera: object | None         # FullModelCamera when the film holds lens irradiance
    meta: dict
    geometry: object = None       # the CameraGeometry it was rendered on


# Scene meta entries the sensor needs to read a render whose film is not a spectrum.
FILM_META_KEYS = ("representation", "channel_names", "channel_integrals_nm", "channel_centroids_nm")


def city_scene_job(inputs: CitySceneInputs, seeds: FrameSeeds, cancel=None) -> Job[CityRender]:
    """Render frame `seeds.index` of a city (a long job: yields Progress with the radiance so far
    as its preview, stops with JobCancelled when `cancel` is set), with the label pass cast
    through the same Mitsuba scene.

    The city's streets and buildings come from inputs.city; its arrangement, the camera pose
    and the render noise from `seeds`. Resolution and field of view: inputs.camera (the
    project's CameraGeometry: sensor rows × cols × scene.oversample samples of pixel pitch /
    oversample, or scene.fov_deg).
    Pinhole path: a pinhole radiance render over camera.hfov_deg; city_optical_image then applies
    the optics level on the same geometry. The visible sun disc is composited where camera rays
    reach the sky (render/sun_disc.py, render.daylight.sun_visible; meta['sun_disc']); not on
    the full-model path below.
    Full model (optics.model 'raytrace' with a lens_file, uses_full_lens_model): Mitsuba traces
    every camera ray through the lens (render.lens_camera, weight 'irradiance'), so the film holds
    sensor irradiance. The lens is prepared as formation/ prepares it and focused on
    camera.focus_distance_m; the film is camera.sensor_width_m wide, so the sample spacing is
    the geometry's. Labels are cast through the lens camera (each pixel's ray through the centre
    of its exit-pupil box), so boxes follow the lens's distortion.
    render.shot_noise_ratio is resolved here: a pilot render through the optics and sensor gives
    the mean electrons N_e of the exposure, and the target error is ratio/√N_e.
    A CitySceneSession does the same and keeps the loaded scene for the next frame."""
    return (yield from CitySceneSession().job(inputs, seeds, cancel))


QUICK_LOOK_MAX_PIXELS = 40_000
"""A quick look (CitySceneSession.job) samples a film coarse enough to have at most this many
pixels (at 1 spp, ~0.04 s of path tracing on this 2-core machine; a 640×480 film at a factor 2,
76,800 pixels, took 0.17 s, and under a CPU hog the window's 1 s goal for the preview of a
camera move was missed)."""


def quick_look_factor(width: int, height: int) -> int:
    """How many times coarser per side a quick look samples a width × height film: the smallest
    factor from 2 up that divides both sides and leaves at most QUICK_LOOK_MAX_PIXELS pixels
    (320×240 → 2, 640×480 → 4, 1920×1080 → 8); when none does, the largest common divisor of
    the sides; 1 when they have none (the film itself is sampled)."""
    common = [f for f in range(2, min(width, height) + 1) if width % f == 0 and height % f == 0]
    for f in common:
        if (width // f) * (height // f) <= QUICK_LOOK_MAX_PIXELS:
            return f
    return common[-1] if common else 1

# Render settings used only when the loaded scene is rendered (sample counts, error targets,
# chunking, the noise seed): a change of these alone keeps the loaded scene. Everything else in
# RenderParams (bands, sampler type, depth, daylight, world) is built into the scene.
RENDER_TIME_FIELDS = frozenset({"spp", "target_rel_error", "shot_noise_ratio", "error_metric", "pilot_spp",
                                "max_spp", "chunk_spp", "preview_spp", "seed"})


def scene_reuse_key(inputs: CitySceneInputs, seeds: FrameSeeds) -> tuple:
    """What a loaded scene depends on: the inputs without the pose and the render-time settings
    (so the window's low-sample preview and its full render of a camera move share one loaded
    scene)."""
    scene_render = inputs.render.model_dump(exclude=set(RENDER_TIME_FIELDS))
    return replace(inputs, pose=None, render=None), scene_render, seeds.arrangement


class CitySceneSession:
    """Renders city frames (city_scene_job) keeping the last loaded Mitsuba scene: a frame that
    differs from the previous one only in its camera pose moves the scene's sensor instead of
    loading the city again (pinhole camera, daylight: a lens camera's rays and the night lights'
    sampling weights depend on the pose). The same inputs and seeds give the same image either way."""

    def __init__(self):
        self._loaded = None          # (reuse key, city, mi_scene, id_table, film)
        self._coarse = None          # (key, the quick look's coarse pinhole)
        self.loads = 0               # Mitsuba scenes loaded so far

    def job(self, inputs: CitySceneInputs, seeds: FrameSeeds, cancel=None,
            quick_look: bool = False, film_edges_nm: tuple[float, ...] | None = None) -> Job[CityRender]:
        """city_scene_job, reusing the loaded scene where only the pose changed.

        film_edges_nm: render box bands between these edges (film.box_bands_between) instead of
        the film inputs.render describes (the window's render shared by every CFA,
        render.shared_bands); None, as for data sets: inputs.render's film.

        quick_look: a first look after a camera move — the label pass records the first
        surface along each ray only (render_labels with max_layers=1: the depth, class and
        instance maps and the visible boxes are exact, the amodal boxes are the visible ones;
        labels.meta['max_layers'] says so), and a pinhole render draws its samples on a film
        quick_look_factor(width, height) times coarser per side, so a quick look costs about the
        same at any film size (each coarse pixel shown over the pixels it covers;
        meta['render']['coarse_factor']; not through the full lens model or a volumetric fog,
        nor when the sides have no common divisor)."""
        from workbench.jobs import JobCancelled, Progress
        from workbench.render.film import box_bands_between
        from workbench.render.labels import render_labels
        from workbench.render.scene_builder import build_scene, move_pinhole, pinhole_sensor
        from workbench.render.spectral import film_for, render_loaded
        from workbench.render.variants import select_variant
        from workbench.scene.city import generate_city, sample_camera_poses
        from workbench.sensor.cfa import SENSOR_SPECTRAL_GRID_NM, channel_qe

        def check():
            if cancel is not None and cancel.is_set():
                raise JobCancelled(f"frame {seeds.index}: cancelled")

        if inputs.scene.kind != "city":
            raise InvalidValueError(f"scene.kind is '{inputs.scene.kind}'; rendering a frame needs scene.kind 'city'")
        yield Progress(0.0, 1.0, f"frame {seeds.index}: building the city")
        recipe = inputs.city.updated(arrangement=seeds.arrangement)
        night = inputs.render.world.lighting == "night"
        full_model = inputs.optics is not None and uses_full_lens_model(inputs.optics)
        reuse_key = None if night or full_model else (scene_reuse_key(inputs, seeds), film_edges_nm)
        loaded = self._loaded if reuse_key is not None and self._loaded is not None \
            and self._loaded[0] == reuse_key else None
        try:                  # counts that do not fit the streets, poses with nothing to aim at: say which
            city = loaded[1] if loaded is not None else generate_city(recipe)
            pose = sample_camera_poses(city, inputs.pose, 1, seeds.pose)[0]
        except ValueError as exc:
            raise StageError("city", f"frame {seeds.index}: {exc}") from None
        camera = inputs.camera
        height, width = camera.shape
        variant = select_variant(inputs.render.variant, strict=inputs.render.variant is not None)
        qe_wl = SENSOR_SPECTRAL_GRID_NM
        fov = camera.hfov_deg
        lens_camera, lens_sensor = None, None
        if full_model:
            from workbench.optics.formation.full_model import full_model_camera
            from workbench.render.lens_camera import lens_sensor_dict
            lens_camera = full_model_camera(inputs.optics, camera)
            lens_sensor = lens_sensor_dict(lens_camera.lens, {"width": width, "height": height},
                                           pinhole_sensor(pose, fov)["to_world"], lens_camera.sensor_width_mm,
                                           weight="irradiance")
        check()
        if loaded is not None:
            _, city, mi_scene, id_table, film = loaded
            move_pinhole(mi_scene, pose, fov)
        else:
            self._loaded = None             # free the old scene before loading the next
            film = box_bands_between(np.asarray(film_edges_nm)) if film_edges_nm is not None else \
                film_for(inputs.render, (qe_wl, np.asarray(channel_qe(inputs.pixels, qe_wl)).T))
            mi_scene, id_table = build_scene(city, pose, fov, width, height, film, inputs.render.daylight,
                                             lens_sensor, max_depth=inputs.render.max_depth, world=inputs.render.world,
                                             sampler=inputs.render.sampler)
            self.loads += 1
            self._coarse = None
        self._loaded = (reuse_key, city, mi_scene, id_table, film) if reuse_key is not None else None
        fog = inputs.render.world.fog
        coarse = None             # not through a lens or a fog medium (the camera carries both)
        factor = quick_look_factor(width, height)
        if quick_look and lens_camera is None and (fog is None or fog.model != "volumetric") and factor > 1:
            coarse = self._coarse_pinhole(pose, fov, film, width, height, factor, inputs.render.sampler)
        yield Progress(0.05, 1.0, f"frame {seeds.index}: label pass")
        labels = render_labels(mi_scene, id_table, width, height, **({"max_layers": 1} if quick_look else {}))
        params = inputs.render.updated(seed=seeds.render)
        meta = {"variant": variant, "fov_deg": fov, "city_seed": recipe.seed, "arrangement": recipe.arrangement,
                "pose": {"position_m": np.asarray(pose.position_m).tolist(), "pan_deg": pose.pan_deg,
                         "tilt_deg": pose.tilt_deg, "roll_deg": pose.roll_deg,
                         "meta": getattr(pose, "meta", {})}}
        if lens_camera is None and not night:   # the disc the directional sun cannot show
            from workbench.render.sun_disc import sun_disc
            disc = sun_disc(film, pose, fov, width, height, inputs.render.daylight, mi_scene=mi_scene)
            meta["sun_disc"] = disc.meta
        else:
            disc = None
            meta["sun_disc"] = {"status": "not composited: " + ("night" if night else
                                                                 "the full lens model bends the camera rays")}

        if fog is not None and fog.model == "koschmieder":
            from workbench.render.koschmieder import koschmieder_fog
            yield Progress(0.07, 1.0, f"frame {seeds.index}: fog airlight")
            fogged = koschmieder_fog(mi_scene, labels.depth_m, city, pose.pan_deg, film, inputs.render.daylight,
                                     inputs.render.world, max_depth=inputs.render.max_depth)
            meta["fog"] = {"model": "koschmieder", "source_heights_m": fogged.profile_z_m.tolist(),
                           "source_function": fogged.profile.tolist(),
                           "upward_elevations_deg": fogged.upward_elevation_deg.tolist(),
                           "upward_source_function": fogged.upward.tolist()}
        else:
            fogged = None

        def with_sun(scene):
            if disc is not None:
                scene.radiance_photons = disc.add_to(scene.radiance_photons)
            if fogged is not None:
                scene.radiance_photons = fogged.apply(scene.radiance_photons)
            return scene

        def rendered(job, start: float, span: float):
            """Drive a render job, yielding its progress as [start, start + span] of this frame."""
            while True:
                try:
                    step = next(job)
                except StopIteration as stop:
                    check()                         # a cancelled render returns its partial image
                    return stop.value
                yield Progress(start + span * step.fraction, 1.0, f"frame {seeds.index}: {step.message}",
                               preview=step.preview)

        if params.shot_noise_ratio is not None:
            pilot = with_sun((yield from rendered(
                render_loaded(mi_scene, film, params.updated(spp=params.pilot_spp, shot_noise_ratio=None),
                              fov_deg=fov, cancel=cancel, name=f"frame {seeds.index} pilot",
                              depth_m=labels.depth_m), 0.1, 0.1)))
            pilot.depth_m = labels.depth_m
            target = sensor_matched_error(inputs, CityRender(pilot, labels, lens_camera, meta, camera),
                                          params.shot_noise_ratio)
            meta["shot_noise_target_rel_error"] = target
            params = params.updated(shot_noise_ratio=None, target_rel_error=target)
        start = 0.2 if inputs.render.shot_noise_ratio is not None else 0.1
        scene = with_sun((yield from rendered(
            render_loaded(mi_scene, film, params, fov_deg=fov, cancel=cancel, name=f"frame {seeds.index}",
                          depth_m=labels.depth_m, coarse_sensor=coarse, coarse_factor=factor),
            start, 1.0 - start)))
        scene.depth_m = labels.depth_m
        meta["spp"] = scene.meta.get("spp")
        meta["render"] = scene.meta
        return CityRender(scene, labels, lens_camera, meta, camera)

    def _coarse_pinhole(self, pose, fov: float, film, width: int, height: int, factor: int, sampler: str):
        """The quick look's coarse pinhole (`factor` times coarser per side) for the loaded scene,
        made once per loaded scene and pointed along `pose`."""
        from workbench.render.scene_builder import coarse_pinhole, move_pinhole
        key = (fov, width, height, factor, sampler)     # reset when a scene is loaded
        if self._coarse is None or self._coarse[0] != key:
            self._coarse = (key, coarse_pinhole(pose, fov, film, width, height, factor, sampler))
        else:
            move_pinhole(None, pose, fov, sensor=self._coarse[1])
        return self._coarse[1]


def render_city_scene(project, seeds: FrameSeeds, on_progress: Callable | None = None,
                      session: CitySceneSession | None = None) -> CityRender:
    """Render frame `seeds.index` of a city project (city_scene_job driven to the end; through
    `session` when given, so a frame of the city it holds reuses the loaded scene)."""
    from workbench.jobs import run_job
    inputs = city_scene_inputs(project)
    return run_job(session.job(inputs, seeds) if session is not None else city_scene_job(inputs, seeds), on_progress)


def sensor_matched_error(inputs: CitySceneInputs, render: CityRender, shot_noise_ratio: float) -> float:
    """Relative render error that is `shot_noise_ratio` × the photon shot noise 1/√N_e, with N_e
    the mean electrons per pixel of the inputs' sensor at its exposure on this render."""
    from workbench.sensor import irradiance_to_signal_rate, resolve_exposure
    oi = city_optical_image(render, inputs.optics, inputs.scene.adjust_illuminance_lux)
    rate = irradiance_to_signal_rate(oi, inputs.sensor)
    exposure_s = float(np.mean(resolve_exposure(rate, inputs.sensor)))
    mean_e = float(np.mean(rate, dtype=np.float64)) * exposure_s
    if not mean_e > 0:
        raise InvalidValueError("render.shot_noise_ratio: the pilot render collects no electrons at this exposure; "
                         "give spp or target_rel_error instead")
    return float(min(shot_noise_ratio / np.sqrt(mean_e), 0.99))


def city_optical_image(render: CityRender, optics, adjust_illuminance_lux: float | None = None):
    """Sensor-plane irradiance of a city render: the optics level on the pinhole radiance (on the
    render's camera geometry), or the full lens camera's film as it is; then the mean-illuminance
    adjustment (scene.adjust_illuminance_lux)."""
    from workbench.stages.optics import form_optical_image, scale_to_mean_illuminance
    film_meta = {k: render.scene.meta[k] for k in FILM_META_KEYS if k in render.scene.meta}
    if render.camera is None:
        oi = form_optical_image(render.scene, optics, render.geometry, adjust_illuminance_lux)
        oi.meta.update(film_meta)
        return oi
    from workbench.optics.formation.full_model import full_model_optical_image
    oi = full_model_optical_image(render.scene.radiance_photons, render.scene.wavelengths_nm, render.camera,
                                  optics, depth_m=render.labels.depth_m, meta=film_meta)
    return scale_to_mean_illuminance(oi, adjust_illuminance_lux, in_place=True)      # its own new array


def render_city_frame(project, seeds: FrameSeeds, on_progress: Callable | None = None,
                      session: CitySceneSession | None = None) -> FrameData:
    """Render frame `seeds.index` of a city project to sensor irradiance with its labels
    (render_city_scene, then city_optical_image); `session` keeps the loaded city between frames."""
    render = render_city_scene(project, seeds, on_progress, session)
    oi = city_optical_image(render, project.optics, project.scene.adjust_illuminance_lux)
    meta = {**render.meta, "optics_model": oi.meta.get("model", project.optics.model),
            "sample_spacing_m": oi.sample_spacing_m, "focal_length_m": oi.focal_length_m,
            "f_number": oi.f_number}
    return FrameData(oi.irradiance_photons, oi.wavelengths_nm, render.labels, meta)


# Seconds per path sample of the llvm variant on one core of the reference machine (city_detection_quick,
# 320×240 at 144 spp multijitter: ~9 s a frame); the estimate scales it by pixels × spp.
SECONDS_PER_SAMPLE = 8.1e-7


def render_estimate_s(project) -> float | None:
    """A rough wall time (s) of one city frame at the project's fixed sampling on one core (None
    for a chart, or when the sampling adapts to an error target)."""
    if project.scene.kind != "city" or project.render.target_rel_error is not None \
            or project.render.shot_noise_ratio is not None:
        return None
    return project.sensor.rows * project.sensor.cols * project.render.spp * SECONDS_PER_SAMPLE


LONG_RENDER_S = 120.0


def long_render_note(project) -> str | None:
    """A line to show before a city render that takes minutes or more (the work is allowed; the
    user should know before waiting), else None."""
    est = render_estimate_s(project)
    if est is None or est <= LONG_RENDER_S:
        return None
    return (f"note: render.spp {project.render.spp:,} at {project.sensor.cols}×{project.sensor.rows} px: about "
            f"{est / 60:,.0f} min per frame on one core (lower render.spp, or set render.target_rel_error)")


"""The staged, cached simulation: scene → optics → pixel signal → sensor → ISP.

Each stage is a pure function of its inputs and of the project sections it reads, so a stage is
recomputed only when one of those changed: moving an ISP parameter re-runs the ISP alone, a
sensor exposure or noise parameter re-runs the exposure from the cached pixel signal, and the
optics run again only when the scene or the optics change.
"""
from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass, field

import numpy as np

from workbench.jobs import CancelToken, Job, Progress, run_job
from workbench.optics.types import OpticalImage
from workbench.project import Project
from workbench.scene.types import Scene
from workbench.sensor.image import SensorImage

STAGES = ("scene", "optics", "signal", "sensor", "isp")

# Sensor fields that change the noise-free pixel signal rate (e⁻/s); every other sensor field
# (exposure, noise, gain, ADC, seed) only changes the exposure stage.
SIGNAL_FIELDS = ("rows", "cols", "pixel_pitch_um", "fill_factor", "cfa_pattern", "filter_file",
                 "photodiode_qe_file", "ir_cut_file")


def _digest(*parts) -> str:
    text = json.dumps(parts, sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()


def camera_hfov_deg(project: Project) -> float:
    """Horizontal field of view (deg) of the sensor behind the project's optics.

    The sensor sits at the image distance of the object in focus (thin-lens law), so a chart
    sampled over this field lands exactly on the pixel grid (the sensor's fast path)."""
    from workbench.optics.formation.geometry import image_distance_m
    from workbench.optics.params import fov_deg
    optics = project.optics
    focus_m = optics.focus_distance_m if optics.focus_distance_m is not None else project.scene.distance_m
    d_mm = 1e3 * image_distance_m(optics.focal_length_m, focus_m)
    return fov_deg(d_mm, project.sensor.cols * project.sensor.pixel_pitch_um * 1e-3)


def check_finite(stage: str, array: np.ndarray) -> None:
    """No NaN/Inf ever leaves a stage (DESIGN.md §3)."""
    if not np.all(np.isfinite(array)):
        raise FloatingPointError(f"stage '{stage}' produced NaN/Inf values; this is a bug or an "
                                 "input outside the model's range — please report the project file")


def make_scene(project: Project) -> Scene:
    """The analytic chart of the project's scene section, sampled on the camera's field."""
    from workbench.scene.charts import CHARTS
    sp = project.scene
    if sp.kind == "city":
        raise ValueError("scene.kind 'city' is rendered, not drawn: use Pipeline(project), whose scene "
                         "stage renders frame 0 of the city")
    size = (project.sensor.rows * sp.oversample, project.sensor.cols * sp.oversample)
    common = dict(size=size, fov_deg=sp.fov_deg or camera_hfov_deg(project),
                  distance_m=sp.distance_m, wavelengths_nm=sp.wavelengths.grid())
    if sp.kind == "uniform":
        return CHARTS["uniform"](illuminant=sp.illuminant, mean_luminance_cd_m2=sp.mean_luminance_cd_m2, **common)
    if sp.kind == "macbeth":
        return CHARTS["macbeth"](illuminant=sp.illuminant, mean_luminance_cd_m2=sp.mean_luminance_cd_m2, **common)
    if sp.kind == "slanted_edge":
        return CHARTS["slanted_edge"](angle_deg=sp.edge_angle_deg, contrast=sp.edge_contrast,
                                      illuminant=sp.illuminant,
                                      mean_luminance_cd_m2=sp.mean_luminance_cd_m2, **common)
    return CHARTS["hdr_tunnel"](exit_luminance_cd_m2=sp.hdr_exit_luminance_cd_m2,
                                tunnel_luminance_cd_m2=sp.hdr_tunnel_luminance_cd_m2, **common)


def scale_to_mean_illuminance(oi: OpticalImage, target_lux: float | None) -> OpticalImage:
    """Rescale the optical image to a mean illuminance (scene.adjust_illuminance_lux); None keeps it."""
    from workbench import spectra
    if target_lux is None:
        return oi
    lux = float(spectra.illuminance_from_photons(
        oi.irradiance_photons.reshape(-1, oi.irradiance_photons.shape[-1]).mean(0), oi.wavelengths_nm))
    if lux <= 0:
        raise ValueError("scene.adjust_illuminance_lux: the optical image is black, it cannot be "
                         "scaled to a mean illuminance")
    oi.irradiance_photons = oi.irradiance_photons * np.float32(target_lux / lux)
    return oi


def form_optical_image(scene: Scene, project: Project) -> OpticalImage:
    """Run the project's optics model, then rescale to a mean illuminance if the scene asks."""
    import workbench.optics.formation  # noqa: F401  (registers the optics models)
    from workbench.optics.types import OPTICS_MODELS
    oi = OPTICS_MODELS[project.optics.model](scene, project.optics)
    return scale_to_mean_illuminance(oi, project.scene.adjust_illuminance_lux)


@dataclass
class PipelineResult:
    scene: Scene
    optical_image: OpticalImage
    signal_rate_e_per_s: np.ndarray
    sensor_image: SensorImage
    isp: object
    stage_times_s: dict[str, float] = field(default_factory=dict)
    labels: object | None = None          # per-pixel/object labels of a rendered city frame


class Pipeline:
    """Cached stages over a project. Call set_project() after edits; run() recomputes what changed."""

    def __init__(self, project: Project, scene: Scene | None = None):
        self._project = project
        self._fixed_scene = scene
        self._cache: dict[str, tuple[str, object]] = {}
        self.stage_times_s: dict[str, float] = {}
        self.recomputed: list[str] = []

    @property
    def project(self) -> Project:
        return self._project

    def set_project(self, project: Project) -> None:
        self._project = project

    def set_scene(self, scene: Scene | None) -> None:
        """Use a given scene (e.g. radiance loaded from disk) instead of the project's chart or city."""
        self._fixed_scene = scene
        self._cache.pop("scene", None)

    # -- keys: what each stage depends on -------------------------------------------------
    def _keys(self) -> dict[str, str]:
        p = self._project
        sensor = p.sensor.model_dump()
        signal_part = {k: sensor[k] for k in SIGNAL_FIELDS if k in sensor}
        scene_key = _digest("fixed" if self._fixed_scene is not None else p.scene.model_dump(),
                            id(self._fixed_scene), p.sensor.rows, p.sensor.cols,
                            p.sensor.pixel_pitch_um, p.optics.focal_length_mm)
        if self._fixed_scene is None and p.scene.kind == "city":
            # A render depends on the city, pose, render settings, the sensor's QE (film range)
            # and, for the full lens model, on the optics it traces.
            from workbench.render.city_frame import uses_full_lens_model
            scene_key = _digest(scene_key, p.seed, p.city, p.pose, p.render, signal_part,
                                p.optics if uses_full_lens_model(p.optics) else None)
        optics_key = _digest(scene_key, p.optics.model_dump(), p.scene.adjust_illuminance_lux)
        signal_key = _digest(optics_key, signal_part)
        sensor_key = _digest(signal_key, sensor)
        isp_key = _digest(sensor_key, p.isp.model_dump())
        return dict(scene=scene_key, optics=optics_key, signal=signal_key, sensor=sensor_key, isp=isp_key)

    def _compute(self, stage: str):
        from workbench.isp import sensor_image_to_srgb
        from workbench.sensor import irradiance_to_signal_rate, resolve_exposure, signal_rate_to_sensor_image
        p = self._project
        if stage == "scene":
            if self._fixed_scene is not None:
                return self._fixed_scene
            if p.scene.kind == "city":
                from workbench.render.city_frame import frame_seeds, render_city_scene
                return render_city_scene(p, frame_seeds(p.seed, 0))
            return make_scene(p)
        if stage == "optics":
            source = self._get("scene")
            if isinstance(source, Scene):
                oi = form_optical_image(source, p)
            else:
                from workbench.render.city_frame import city_optical_image
                oi = city_optical_image(source, p)
            check_finite("optics", oi.irradiance_photons)
            return oi
        if stage == "signal":
            rate = irradiance_to_signal_rate(self._get("optics"), p.sensor)
            check_finite("signal", rate)
            return rate
        if stage == "sensor":
            oi = self._get("optics")
            rate = self._get("signal")
            image = signal_rate_to_sensor_image(rate, p.sensor, resolve_exposure(rate, p.sensor),
                                                wavelengths_nm=oi.wavelengths_nm)
            check_finite("sensor", image.dn)
            return image
        result = sensor_image_to_srgb(self._get("sensor"), p.isp)
        check_finite("isp", result.srgb)
        return result

    def _get(self, stage: str):
        key = self._keys()[stage]
        hit = self._cache.get(stage)
        if hit is not None and hit[0] == key:
            return hit[1]
        # Upstream stages are fetched (and timed) before this stage's own clock starts.
        idx = STAGES.index(stage)
        if idx > 0:
            self._get(STAGES[idx - 1])
        t0 = time.perf_counter()
        value = self._compute(stage)
        self.stage_times_s[stage] = time.perf_counter() - t0
        self.recomputed.append(stage)
        self._cache[stage] = (key, value)
        return value

    def scene(self) -> Scene:
        source = self._get("scene")
        return source if isinstance(source, Scene) else source.scene

    def labels(self):
        """Per-pixel and per-object labels of a rendered city frame (None for charts)."""
        return getattr(self._get("scene"), "labels", None)

    def optical_image(self) -> OpticalImage:
        return self._get("optics")

    def signal_rate(self) -> np.ndarray:
        return self._get("signal")

    def sensor_image(self) -> SensorImage:
        return self._get("sensor")

    def isp_result(self):
        return self._get("isp")

    def run_job(self, cancel: CancelToken | None = None) -> Job[PipelineResult]:
        """The pipeline as a long job: yields Progress per stage, checks cancel between stages."""
        self.recomputed = []
        for i, stage in enumerate(STAGES):
            if cancel is not None:
                cancel.check()
            yield Progress(i, len(STAGES), stage)
            self._get(stage)
        yield Progress(len(STAGES), len(STAGES), "done")
        return PipelineResult(self.scene(), self.optical_image(), self.signal_rate(),
                              self.sensor_image(), self.isp_result(), dict(self.stage_times_s), self.labels())

    def run(self, cancel: CancelToken | None = None) -> PipelineResult:
        return run_job(self.run_job(cancel))

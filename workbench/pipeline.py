"""The staged, cached simulation: scene → optics → pixel signal → sensor → ISP.

The pipeline only orchestrates: the stage functions live in workbench.stages (camera geometry,
charts, optical image), workbench.render.city_frame (city renders), workbench.sensor and
workbench.isp. Each stage is a pure function of its inputs, and its cache key is the digest of
exactly those inputs (stage_inputs) chained to its upstream stage's key, so a stage is
recomputed only when something it reads changed: moving an ISP parameter re-runs the ISP alone,
an exposure or noise parameter re-runs the sensor from the cached pixel signal, and the scene
is re-sampled whenever the camera geometry (focus, lens, sensor size, pixel pitch) changes.

The cache keeps several results per stage, least recently used first out, within a memory budget
(cache_mb), so going back to an earlier camera pose or sensor (Undo) finds its stages cached.

Thread safety (the window drives it from a worker thread): every run works on one Snapshot of
the project, its camera geometry and its keys, taken when the run starts; set_project may be
called from another thread at any time and affects the next run only; the cache is locked, and
a result is stored under the key of the snapshot it was computed from.
"""
from __future__ import annotations

import dataclasses
import itertools
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from workbench.errors import InvalidValueError, check_finite
from workbench.jobs import CancelToken, Job, Progress, run_job
from workbench.optics.formation.geometry import CameraGeometry
from workbench.optics.types import OpticalImage
from workbench.project import Project
from workbench.scene.types import Scene
from workbench.sensor.image import SensorImage
from workbench.stages.geometry import project_geometry
from workbench.stages.keys import digest

STAGES = ("scene", "optics", "signal", "sensor", "isp")
CACHE_MB = 1024.0            # default memory budget of a pipeline's stage cache
CACHE_ENTRIES_PER_STAGE = 8


def result_nbytes(value, depth: int = 3) -> int:
    """Bytes of the numpy arrays a stage result holds (arrays, dataclasses, objects, dicts, lists,
    followed `depth` levels down): what keeping it in the cache costs."""
    if isinstance(value, np.ndarray):
        return int(value.nbytes)
    if depth == 0 or value is None or isinstance(value, (str, bytes, int, float, bool)):
        return 0
    if isinstance(value, dict):
        items = value.values()
    elif isinstance(value, (list, tuple)):
        items = value
    elif dataclasses.is_dataclass(value):
        items = (getattr(value, f.name) for f in dataclasses.fields(value))
    elif hasattr(value, "__dict__"):
        items = vars(value).values()
    else:
        return 0
    return sum(result_nbytes(v, depth - 1) for v in items)


@dataclass(frozen=True)
class FixedScene:
    """A scene given to the pipeline (set_scene) instead of the project's chart or city; `token`
    changes with every set_scene, so it keys the scene stage."""

    scene: Scene = field(compare=False)
    token: int


def stage_inputs(project: Project, camera: CameraGeometry, fixed: FixedScene | None = None) -> dict[str, object]:
    """What each stage reads, per stage: the scene stage the chart section and the camera
    geometry, or a city render's inputs (city_frame.city_scene_inputs), or the fixed scene; the
    optics stage the optics section, the geometry the scene was sampled for (None for a fixed
    scene: its own field of view) and the illuminance adjustment; the signal stage the pixel
    response; the sensor stage the whole sensor section; the ISP its section."""
    if fixed is not None:
        scene_in, optics_camera = ("fixed scene", fixed.token), None
    elif project.scene.kind == "city":
        from workbench.render.city_frame import city_scene_inputs
        scene_in, optics_camera = city_scene_inputs(project), camera
    else:
        scene_in, optics_camera = ("chart", project.scene, camera), camera
    return {"scene": scene_in,
            "optics": (project.optics, optics_camera, project.scene.adjust_illuminance_lux),
            "signal": project.sensor.pixel_response,
            "sensor": project.sensor,
            "isp": project.isp}


def stage_keys(inputs: dict[str, object]) -> dict[str, str]:
    """Each stage's key: its inputs' digest chained to the upstream stage's key."""
    keys, upstream = {}, ""
    for stage in STAGES:
        keys[stage] = upstream = digest(stage, upstream, inputs[stage])
    return keys


@dataclass(frozen=True)
class Snapshot:
    """What one run works on: the project, the fixed scene if any, the camera geometry, and each
    stage's inputs and key, all taken together when the run starts."""

    project: Project
    fixed: FixedScene | None
    camera: CameraGeometry
    inputs: dict = field(compare=False)
    keys: dict = field(compare=False)


# -- the stage computations: each sees its own inputs and the upstream result only ----------------
def _scene_job(inputs, cancel, city_renderer=None) -> Job:
    if isinstance(inputs, tuple):              # ("chart", scene section, camera geometry)
        from workbench.stages.scene import chart_scene
        return chart_scene(inputs[1], inputs[2])
    from workbench.render.city_frame import city_scene_job, frame_seeds
    return (yield from (city_renderer or city_scene_job)(inputs, frame_seeds(inputs.seed, 0), cancel))


def _optics(inputs, source):
    optics, camera, lux = inputs
    if isinstance(source, Scene):
        from workbench.stages.optics import form_optical_image
        oi = form_optical_image(source, optics, camera, lux)
    else:
        from workbench.render.city_frame import city_optical_image
        oi = city_optical_image(source, optics, lux)
    check_finite("optics", oi.irradiance_photons)
    return oi


def _signal(pixels, oi):
    from workbench.sensor import irradiance_to_signal_rate
    return check_finite("signal", irradiance_to_signal_rate(oi, pixels))


def _sensor(sensor, upstream):
    from workbench.sensor import resolve_exposure, signal_rate_to_sensor_image
    from workbench.sensor.signal import colour_wavelengths_nm
    oi, rate = upstream
    image = signal_rate_to_sensor_image(rate, sensor, resolve_exposure(rate, sensor),
                                        wavelengths_nm=colour_wavelengths_nm(oi))
    check_finite("sensor", image.dn)
    return image


def _isp(isp, image):
    from workbench.isp import sensor_image_to_srgb
    result = sensor_image_to_srgb(image, isp)
    check_finite("isp", result.srgb)
    return result


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
    """Cached stages over a project. Call set_project() after edits (from any thread); run() or
    run_job() recomputes what changed, on a snapshot of the project taken when it starts.
    city_renderer(inputs, seeds, cancel) → Job[CityRender] renders city scenes (default
    city_frame.city_scene_job in this process; the window passes a render_worker.RenderWorker's job).

    recomputed lists the stages the latest run computed so far (a stage getter adds the stages it
    computes); stage_times_s holds each stage's latest compute time (s)."""

    def __init__(self, project: Project, scene: Scene | None = None, cache_mb: float = CACHE_MB,
                 city_renderer: Callable | None = None):
        self._lock = threading.RLock()
        self._tokens = itertools.count(1)
        self._project = project
        self._fixed = FixedScene(scene, next(self._tokens)) if scene is not None else None
        self._cache: dict[str, OrderedDict] = {stage: OrderedDict() for stage in STAGES}  # key → (value, bytes, use)
        self._uses = itertools.count()
        self.cache_limit_bytes = int(cache_mb * 2 ** 20)
        self.city_renderer = city_renderer
        self.stage_times_s: dict[str, float] = {}
        self.recomputed: list[str] = []
        self._run_snapshot: Snapshot | None = None     # the last run's, reused by the accessors

    @property
    def project(self) -> Project:
        with self._lock:
            return self._project

    def set_project(self, project: Project) -> None:
        """Use `project` from the next run on (a run in progress keeps its snapshot)."""
        with self._lock:
            self._project = project

    def set_scene(self, scene: Scene | None) -> None:
        """Use a given scene (e.g. radiance loaded from disk) instead of the project's chart or city."""
        with self._lock:
            self._fixed = FixedScene(scene, next(self._tokens)) if scene is not None else None

    def snapshot(self) -> Snapshot:
        """The project, fixed scene, camera geometry, stage inputs and keys a run started now uses."""
        with self._lock:
            project, fixed = self._project, self._fixed
        camera = project_geometry(project)
        inputs = stage_inputs(project, camera, fixed)
        return Snapshot(project, fixed, camera, inputs, stage_keys(inputs))

    def _accessor_snapshot(self) -> Snapshot:
        """The last run's snapshot while the project and fixed scene are the very objects it was
        taken of (an accessor after a run: optical_image(), isp_result() … each took ~2 ms of
        key hashing on a city), else a new one. A run always takes a new one, so a spectrum file
        edited on disk is seen by the next run."""
        with self._lock:
            snap = self._run_snapshot
            if snap is not None and snap.project is self._project and snap.fixed is self._fixed:
                return snap
        return self.snapshot()

    def cached(self, stage: str, key: str):
        """The cached result of `stage` if it was computed for `key`, else None (a hit becomes the
        most recently used)."""
        with self._lock:
            entries = self._cache[stage]
            if key not in entries:
                return None
            value, size, _ = entries.pop(key)
            entries[key] = (value, size, next(self._uses))
            return value

    def cache_bytes(self) -> int:
        """Bytes of arrays the cache holds now."""
        with self._lock:
            return sum(size for entries in self._cache.values() for _, size, _ in entries.values())

    def _store(self, stage: str, key: str, value) -> None:
        """Cache a result; drop the least recently used results (never a stage's newest) until each
        stage keeps at most CACHE_ENTRIES_PER_STAGE and all of them fit the memory budget."""
        with self._lock:
            entries = self._cache[stage]
            entries[key] = (value, result_nbytes(value), next(self._uses))
            while len(entries) > CACHE_ENTRIES_PER_STAGE:
                entries.popitem(last=False)
            while self.cache_bytes() > self.cache_limit_bytes:
                older = [(e[k][2], st, k) for st, e in self._cache.items() for k in list(e)[:-1]]
                if not older:
                    break
                _, st, k = min(older)
                del self._cache[st][k]

    # -- running ------------------------------------------------------------------------------
    def _stage_job(self, snap: Snapshot, stage: str, upstream, cancel, record: list[str]) -> Job:
        key = snap.keys[stage]
        if stage == "scene" and snap.fixed is not None:
            return snap.fixed.scene
        value = self.cached(stage, key)
        if value is not None:
            return value
        t0 = time.perf_counter()
        inputs = snap.inputs[stage]
        if stage == "scene":
            value = yield from _scene_job(inputs, cancel, self.city_renderer)
        else:
            value = {"optics": _optics, "signal": _signal, "sensor": _sensor, "isp": _isp}[stage](inputs, upstream)
        self._store(stage, key, value)
        with self._lock:
            self.stage_times_s = {**self.stage_times_s, stage: time.perf_counter() - t0}
            record.append(stage)
        return value

    def _job(self, upto: str, cancel: CancelToken | None, new_run: bool = True) -> Job[dict]:
        """Run the stages up to `upto` on one snapshot; yields Progress (done/total in stages,
        a render's own progress and preview inside the scene stage); returns {stage: result}."""
        if upto not in STAGES:
            raise InvalidValueError(f"upto must be one of {STAGES}, got {upto!r}")
        snap = self.snapshot() if new_run else self._accessor_snapshot()
        if new_run:
            with self._lock:
                self._run_snapshot = snap
        stages = STAGES[:STAGES.index(upto) + 1]
        with self._lock:                       # recomputed stages, as they finish
            if new_run:
                self.recomputed = []
            record = self.recomputed
        results: dict[str, object] = {}
        for i, stage in enumerate(stages):
            if cancel is not None:
                cancel.check()
            yield Progress(i, len(stages), stage)
            upstream = {"scene": None, "optics": results.get("scene"), "signal": results.get("optics"),
                        "sensor": (results.get("optics"), results.get("signal")),
                        "isp": results.get("sensor")}[stage]
            job = self._stage_job(snap, stage, upstream, cancel, record)
            while True:
                try:
                    step = next(job)
                except StopIteration as stop:
                    results[stage] = stop.value
                    break
                yield Progress(i + step.fraction, len(stages), f"{stage}: {step.message}", step.preview)
        yield Progress(len(stages), len(stages), "done")
        return results

    def _run_to(self, stage: str):
        return run_job(self._job(stage, None, new_run=False))[stage]

    def scene_stage_result(self):
        """The scene stage's result: the Scene of a chart or fixed scene, or the CityRender of a
        city frame (render, labels, meta)."""
        return self._run_to("scene")

    def scene(self) -> Scene:
        source = self._run_to("scene")
        return source if isinstance(source, Scene) else source.scene

    def labels(self):
        """Per-pixel and per-object labels of a rendered city frame (None for charts)."""
        return getattr(self._run_to("scene"), "labels", None)

    def camera_geometry(self) -> CameraGeometry:
        """The camera geometry of the current project (what the scene is sampled on)."""
        return self.snapshot().camera

    def optical_image(self) -> OpticalImage:
        return self._run_to("optics")

    def signal_rate(self) -> np.ndarray:
        return self._run_to("signal")

    def sensor_image(self) -> SensorImage:
        return self._run_to("sensor")

    def isp_result(self):
        return self._run_to("isp")

    def run_job(self, cancel: CancelToken | None = None, upto: str = "isp") -> Job[PipelineResult]:
        """The pipeline as a long job on one snapshot of the project: yields Progress per stage
        (and a city render's progress with previews), checks `cancel` between stages and render
        chunks (JobCancelled). upto='sensor' etc. stops early; the result's later fields are None."""
        results = yield from self._job(upto, cancel)
        source = results["scene"]
        return PipelineResult(source if isinstance(source, Scene) else source.scene, results.get("optics"),
                              results.get("signal"), results.get("sensor"), results.get("isp"),
                              dict(self.stage_times_s), getattr(source, "labels", None))

    def run(self, cancel: CancelToken | None = None, on_progress: Callable[[Progress], None] | None = None
            ) -> PipelineResult:
        return run_job(self.run_job(cancel), on_progress)

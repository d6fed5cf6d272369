"""The live pipeline: one background thread runs workbench.pipeline.Pipeline on the newest project.

"Latest edit wins": submit() during a run cancels it through its CancelToken and the thread starts
again on the newest project; only the stages downstream of the edit recompute (the pipeline's
cache). A city whose render inputs changed, and whose render is not cached (Undo finds it), is
drawn progressively: first a low-sample preview, then the project's own sampling, each cancelled
by the next edit. City renders run in a render worker process (render.render_worker), which keeps
the scene loaded between camera moves; nothing Mitsuba does holds this process's GIL. A city is
rendered in bands that every CFA pattern's bands are sums of (render.shared_bands), so no CFA
edit renders it again. Results reach the GUI thread as
numpy arrays (Frame) through a queued signal; the GUI thread never waits on the worker.
"""
from __future__ import annotations

import functools
import logging
import threading
import time
import weakref
from dataclasses import dataclass, field

import numpy as np
from PySide6.QtCore import QObject, Signal

from workbench.display8 import Display8
from workbench.jobs import CancelToken, JobCancelled
from workbench.pipeline import Pipeline
from workbench.project import Project

log = logging.getLogger("workbench.gui.live")

PREVIEW_SPP = 1          # samples per pixel of the first, quick city render after a camera move: a
# quick look (render.city_frame.CitySceneSession.job): sampled on a coarser film (at most
# QUICK_LOOK_MAX_PIXELS pixels: 160×120 for a 640×480 sensor), visible labels only
WORKER_THREADS = 1       # torch / OpenMP / Mitsuba threads of the worker, so the GUI keeps a core
# The city render worker is a process of its own: it uses every core of the thread budget, niced so
# that the window's threads (GUI, live worker, 3-D view) take a core whenever they need one.
RENDER_NICE = 10
UNIT_LEVELS = (0.0, 1.0)  # the display levels of the irradiance, linear and sRGB panes (raw: 0…max DN)
IRRADIANCE_PREVIEWS = 4   # irradiance panes' sRGB kept per optical image (Undo/Redo find theirs)


def limit_worker_threads(n: int = WORKER_THREADS) -> None:
    """Cap the compute libraries the worker uses (process-wide) so the GUI thread is not starved;
    called before every run, as torch and Dr.Jit load lazily. OpenMP/BLAS pools are capped by
    app.py's environment before numpy loads."""
    import sys
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(n)
    if "drjit" in sys.modules:          # imported by the first render (which sets its LLVM path)
        sys.modules["drjit"].set_thread_count(n)


@dataclass
class Frame:
    """One pipeline result, as the preview panes need it (all numpy, made in the worker).

    irradiance_photons: H×W×Nλ photons/s/m²/nm; irradiance_rgb: its H×W×3 sRGB preview in [0,1].
    raw_dn: H×W digital numbers; max_dn: the clip code; cfa_tile/channel_names: the mosaic.
    linear: H×W×K demosaiced channels in [0,1]; linear_rgb: H×W×3 of them for display (linear
    itself for an R, G, B sensor).
    srgb: H×W×3 in [0,1]. signal_rate_e_per_s: H×W noise-free pixel signal (for the sweep)."""

    project: Project
    irradiance_photons: np.ndarray
    wavelengths_nm: np.ndarray
    colour_wavelengths_nm: np.ndarray      # where the sensor records its QE for the colour fit
    irradiance_rgb: np.ndarray
    raw_dn: np.ndarray
    max_dn: float
    cfa_tile: np.ndarray
    channel_names: list[str]
    linear: np.ndarray
    linear_rgb: np.ndarray
    srgb: np.ndarray
    signal_rate_e_per_s: np.ndarray
    optics_level: str
    optics_reason: str
    stage_times_s: dict[str, float]
    recomputed: list[str]
    preview: bool = False
    submitted_at: float = 0.0
    isp_notes: list[str] = field(default_factory=list)
    readouts: dict | None = None           # metrics.frame.frame_readouts of this frame
    display8: dict = field(default_factory=dict)   # pane name → display8.Display8 of its image


def _optics_level(oi, project: Project) -> tuple[str, str]:
    meta = oi.meta or {}
    auto = meta.get("auto")
    if isinstance(auto, dict):
        return f"auto → {auto.get('chosen', meta.get('model', '?'))}", str(auto.get("why", ""))
    return str(meta.get("model", project.optics.model)), ""


class FrameBuilder:
    """Turns a pipeline's stages into a Frame, re-deriving display arrays only for stages that ran."""

    def __init__(self) -> None:
        self._irr_rgb: dict[int, tuple] = {}   # id(optical image) → (weak reference to it, sRGB preview)
        self._readouts_key = None      # the sensor image the read-outs were taken from
        self._readouts = None
        self._raw_display: tuple = (None, None)   # (sensor image, display8.Display8 of its DN)

    def _irradiance_rgb(self, oi) -> Display8:
        """The irradiance pane's sRGB of `oi` with its 8-bit copy, kept for the last
        IRRADIANCE_PREVIEWS optical images (Undo and Redo bring back one the stage cache still
        holds: 10–20 ms each otherwise)."""
        from workbench.previews import irradiance_preview
        hit = self._irr_rgb.pop(id(oi), None)
        if hit is None or hit[0]() is not oi:
            rgb = irradiance_preview(oi.irradiance_photons, oi.wavelengths_nm, oi.meta).astype(np.float32)
            hit = (weakref.ref(oi), Display8.of(rgb, UNIT_LEVELS))
        self._irr_rgb[id(oi)] = hit                    # newest last
        while len(self._irr_rgb) > IRRADIANCE_PREVIEWS:
            self._irr_rgb.pop(next(iter(self._irr_rgb)))
        return hit[1]

    def _raw_display8(self, img) -> Display8:
        """The raw pane's 8-bit copy of `img`'s DN (an ISP edit keeps the sensor image's)."""
        if self._raw_display[0] is not img:
            self._raw_display = (img, Display8.of(img.dn, (0.0, float(img.max_dn))))
        return self._raw_display[1]

    def readouts(self, pipe: Pipeline, project: Project) -> dict:
        """metrics.frame.frame_readouts of the pipeline's sensor image (kept: an ISP edit keeps
        the sensor's read-outs)."""
        from workbench.metrics.frame import frame_readouts
        img = pipe.sensor_image()
        if self._readouts_key is not img:
            self._readouts = frame_readouts(img, pipe.signal_rate(), project.sensor, pipe.labels())
            self._readouts_key = img
        return self._readouts

    def build(self, pipe: Pipeline, project: Project, preview: bool, submitted_at: float,
              readouts: bool = True) -> Frame:
        """The Frame of the pipeline's results; with readouts=False a full frame carries its
        read-outs only if they are known (its sensor image's), the caller adds them later
        (readouts()), after the frame is on screen."""
        from workbench.previews import channels_to_rgb
        from workbench.sensor.signal import colour_wavelengths_nm
        oi = pipe.optical_image()
        img = pipe.sensor_image()
        isp = pipe.isp_result()
        irradiance = self._irradiance_rgb(oi)
        linear_rgb = np.asarray(channels_to_rgb(isp.linear, list(isp.channel_names)), dtype=np.float32)
        srgb = np.asarray(isp.srgb, dtype=np.float32)
        display8 = {"irradiance": irradiance, "raw": self._raw_display8(img),
                    "linear": Display8.of(linear_rgb, UNIT_LEVELS), "srgb": Display8.of(srgb, UNIT_LEVELS)}
        level, reason = _optics_level(oi, project)
        if preview:
            frame_readouts = None
        elif readouts:
            frame_readouts = self.readouts(pipe, project)
        else:
            frame_readouts = self._readouts if self._readouts_key is img else None
        return Frame(project=project, irradiance_photons=oi.irradiance_photons,
                     wavelengths_nm=np.asarray(oi.wavelengths_nm), irradiance_rgb=irradiance.source,
                     colour_wavelengths_nm=colour_wavelengths_nm(oi),
                     raw_dn=img.dn, max_dn=float(img.max_dn), cfa_tile=np.asarray(img.cfa_tile),
                     channel_names=list(img.channel_names), linear=isp.linear,
                     linear_rgb=linear_rgb, srgb=srgb, signal_rate_e_per_s=pipe.signal_rate(),
                     optics_level=level, optics_reason=reason, stage_times_s=dict(pipe.stage_times_s),
                     recomputed=list(pipe.recomputed), preview=preview, submitted_at=submitted_at,
                     isp_notes=list(getattr(isp, "notes", []) or []), readouts=frame_readouts,
                     display8=display8)


WINDOW_BANDS = 16        # a city rendered in the sensor's channels is shown from this many bands


def window_project(project: Project) -> Project:
    """The project the window simulates: a city rendered in the sensor's own channels (the data
    sets' cheap film, which a sensor edit invalidates) is rendered spectrally instead, so every
    sensor, CFA and ISP edit reuses the render (render.city_frame.city_scene_inputs; a CFA edit
    that moves the bands takes them from the shared render, render.shared_bands)."""
    if project.scene.kind == "city" and project.render.representation == "sensor":
        return project.updated(render=project.render.updated(representation="bands", band_count=WINDOW_BANDS))
    return project


class LiveRunner(QObject):
    """Owns one worker thread and one Pipeline; submit(project) → frameReady(Frame) later.

    Signals (delivered on the GUI thread): frameReady(Frame), progress(str stage, float 0…1),
    failed(str message), busyChanged(bool), readoutsReady(Frame, dict): the read-outs of a full
    frame that came without them (a sensor edit's), taken once the worker is idle after it."""

    frameReady = Signal(object)
    readoutsReady = Signal(object, object)
    progress = Signal(str, float)
    failed = Signal(str)
    busyChanged = Signal(bool)

    def __init__(self, parent=None, preview_spp: int = PREVIEW_SPP):
        super().__init__(parent)
        self.preview_spp = preview_spp
        self._cond = threading.Condition()
        self._pending: tuple[Project, float] | None = None
        self._token: CancelToken | None = None
        self._stop = False
        self.pipeline: Pipeline | None = None
        self._preview_pipeline: Pipeline | None = None
        self._builder = FrameBuilder()
        self._preview_builder = FrameBuilder()
        self._last_rendered: tuple | None = None    # what the last full frame's city render read
        self._readouts_due: tuple[Frame, Project] | None = None   # the newest frame without read-outs
        self.render_worker = None                  # started with the first city project
        self.city_renderer = None                  # render.shared_bands.SharedBandRenderer over the worker
        self._warmed = False
        self._thread = threading.Thread(target=self._loop, name="workbench-live", daemon=True)
        self._thread.start()

    # -- GUI thread ------------------------------------------------------------------------
    def submit(self, project: Project) -> None:
        """Run the pipeline on `project` as soon as possible; supersedes any pending or running run."""
        with self._cond:
            self._pending = (project, time.perf_counter())
            if self._token is not None:
                self._token.cancel()
            self._cond.notify()

    def cancel(self) -> None:
        """Stop the current run and drop any pending one."""
        with self._cond:
            self._pending = None
            if self._token is not None:
                self._token.cancel()

    def shutdown(self, timeout_s: float = 2.0) -> None:
        """Stop: cancel the run, end the render worker process (a render in flight is abandoned)
        and wait at most timeout_s for the thread, which then has no render to wait for."""
        with self._cond:
            self._stop = True
            self._pending = None
            if self._token is not None:
                self._token.cancel()
            self._cond.notify()
        if self.render_worker is not None:
            self.render_worker.close()
        self._thread.join(timeout_s)

    @property
    def busy(self) -> bool:
        with self._cond:
            return self._token is not None or self._pending is not None

    # -- worker thread ---------------------------------------------------------------------
    def _loop(self) -> None:
        while True:
            with self._cond:
                while self._pending is None and not self._stop:
                    self._cond.wait()
                if self._stop:
                    return
                project, submitted_at = self._pending
                self._pending = None
                token = self._token = CancelToken()
            self.busyChanged.emit(True)
            limit_worker_threads()
            if not self._warmed:
                self._warm_up(project)
            try:
                self._run(project, submitted_at, token)
            except JobCancelled:
                pass
            except Exception as exc:  # noqa: BLE001 — shown to the user, the worker lives on
                if not token.cancelled:
                    self.failed.emit(f"{type(exc).__name__}: {exc}")
            finally:
                with self._cond:
                    self._token = None
                    idle = self._pending is None
                if idle:
                    self.busyChanged.emit(False)
            if idle:
                self._take_due_readouts()

    def _take_due_readouts(self) -> None:
        """The read-outs of the newest full frame, if it came without them (readoutsReady): taken
        after the frame is on screen, so a sensor edit's frame does not wait ~4 ms for them."""
        due, self._readouts_due = self._readouts_due, None
        if due is None:
            return
        frame, document_project = due
        try:
            readouts = self._builder.readouts(self.pipeline, document_project)
        except Exception:  # noqa: BLE001 — the frame is shown; the metrics dock keeps its last read-outs
            log.exception("frame read-outs failed")
            return
        self.readoutsReady.emit(frame, readouts)

    def _warm_up(self, project: Project) -> None:
        """Once, before the first run (the window is still opening, nobody is editing yet; ~80 ms
        in a fresh process): load the pixel kernels a later edit may call (workbench.warm_up), so
        that edit does not pay for it. Done after the first frame, it delayed an edit made right
        then by as much."""
        from workbench.warm_up import warm_up_pixel_kernels
        self._warmed = True
        try:
            warm_up_pixel_kernels(window_project(project))
        except Exception:  # noqa: BLE001 — only a head start; the edit itself reports any error
            log.exception("warming up the pixel kernels failed")

    def _drive(self, pipe: Pipeline, token: CancelToken) -> None:
        job = pipe.run_job(token)
        while True:
            try:
                p = next(job)
            except StopIteration:
                return
            token.check()
            self.progress.emit(p.message, p.fraction)

    def _run(self, document_project: Project, submitted_at: float, token: CancelToken) -> None:
        self._readouts_due = None                    # this run's frame supersedes the last one
        project = window_project(document_project)
        if project.scene.kind == "city" and self.render_worker is None:
            from workbench.compute.pixel_threads import budget_cores
            from workbench.render.render_worker import RenderWorker
            from workbench.render.shared_bands import SharedBandRenderer
            self.render_worker = RenderWorker(threads=budget_cores(), nice=RENDER_NICE)
            self.city_renderer = SharedBandRenderer(self.render_worker.job)
        renderer = None if self.city_renderer is None else functools.partial(self.city_renderer.job, project=project)
        if self.pipeline is None:
            self.pipeline = Pipeline(project)
        self.pipeline.city_renderer = renderer
        self.pipeline.set_project(project)
        rendered = None
        if project.scene.kind == "city":       # what is rendered: a CFA edit keeps it (render.shared_bands)
            from workbench.render.shared_bands import rendered_inputs
            rendered = rendered_inputs(project)
        if (rendered is not None and rendered != self._last_rendered and project.render.spp is not None
                and project.render.spp > self.preview_spp
                and self.pipeline.cached("scene", self.pipeline.snapshot().keys["scene"]) is None):
            quick = project.updated(render=project.render.updated(spp=self.preview_spp, chunk_spp=self.preview_spp,
                                                                  preview_spp=self.preview_spp))
            if self._preview_pipeline is None:
                self._preview_pipeline = Pipeline(quick)
            self._preview_pipeline.city_renderer = (None if renderer is None else functools.partial(
                self.city_renderer.job, project=quick, quick_look=True))
            self._preview_pipeline.set_project(quick)
            self._drive(self._preview_pipeline, token)
            token.check()
            self.frameReady.emit(self._preview_builder.build(self._preview_pipeline, document_project, True,
                                                             submitted_at))
        self._drive(self.pipeline, token)
        token.check()
        frame = self._builder.build(self.pipeline, document_project, False, submitted_at, readouts=False)
        self._last_rendered = rendered
        self._readouts_due = None if frame.readouts is not None else (frame, document_project)
        self.frameReady.emit(frame)

"""Resumable labelled data sets: N city frames rendered to irradiance + labels, COCO JSON, manifest.

Frame i is a pure function of the project and i: its seeds (city arrangement, camera pose, render
noise) come from numpy's SeedSequence([project.seed, DATASET_SEED_TAG, i]), so a set can be
extended, resumed or re-rendered frame by frame and gives the same arrays.

Layout of out_dir:
  dataset_spec.json        what the frames were made from (project, storage); written first
  frames/frame_000007.npz  one frame, written whole or not at all (temporary name + os.replace)
  coco.json, manifest.json written (atomically) once every frame exists

Irradiance storage: 'float16' keeps E / 2^k as float16 with the power of two 2^k chosen so that the
frame's maximum lies in (2^14, 2^15]; decoding multiplies exactly, so the only error is float16
rounding: relative error ≤ 2^-11 (0.049 %) for values above max · 2^-28 (3.7e-9 · max), absolute
error ≤ 2^-25 · 2^k below that. 'float32' stores the array as rendered (no error).
"""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import time
import zipfile
from dataclasses import asdict, dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable, Generator

import numpy as np

from workbench.compute.local import run_jobs
from workbench.jobs import CancelToken, Progress
from workbench.render.labels import Labels, labels_from_arrays, labels_to_coco

DATASET_FORMAT = "camera-workbench-dataset"
FRAME_FORMAT = "camera-workbench-frame"
FRAME_VERSION = 1
DATASET_SEED_TAG = 0x6461_7461       # separates data-set seeds from other uses of the project seed
IRRADIANCE_DTYPES = ("float16", "float32")
FLOAT16_REL_ERROR = 2.0 ** -11
FRAMES_DIR = "frames"
IRRADIANCE_NOTE = ("float16: E/2^k stored, 2^k puts the frame maximum in (2^14, 2^15]; relative error "
                   "<= 2^-11 above 2^-28 * max, absolute error <= 2^-25 * 2^k below; float32: exact")


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
                        meta={"frame": data.meta})


def encode_irradiance(irradiance: np.ndarray, dtype: str) -> tuple[np.ndarray, float]:
    """(stored array, scale) with irradiance ≈ stored × scale (see the module docstring)."""
    if dtype not in IRRADIANCE_DTYPES:
        raise ValueError(f"irradiance dtype '{dtype}' not allowed; allowed: {', '.join(IRRADIANCE_DTYPES)}")
    arr = np.asarray(irradiance, dtype=np.float32)
    if not np.all(np.isfinite(arr)) or (arr.size and arr.min() < 0):
        raise ValueError("irradiance has NaN/Inf or negative values; refusing to store it")
    if dtype == "float32":
        return arr, 1.0
    peak = float(arr.max(initial=0.0))
    scale = 2.0 ** (np.ceil(np.log2(peak)) - 15) if peak > 0 else 1.0
    return (arr.astype(np.float64) / scale).astype(np.float16), float(scale)   # exact division


def decode_irradiance(stored: np.ndarray, scale: float) -> np.ndarray:
    """Inverse of encode_irradiance: float32 photons/s/m²/nm."""
    return (stored.astype(np.float64) * scale).astype(np.float32)


def frame_path(out_dir: str | os.PathLike, index: int) -> Path:
    return Path(out_dir) / FRAMES_DIR / f"frame_{index:06d}.npz"


def write_frame(path: str | os.PathLike, data: FrameData, header: dict, dtype: str) -> None:
    """Write one frame atomically: compressed npz under a temporary name, fsync, os.replace."""
    path = Path(path)
    stored, scale = encode_irradiance(data.irradiance_photons, dtype)
    if stored.shape[:2] != data.labels.shape:
        raise ValueError(f"frame {header.get('index')}: irradiance is {stored.shape[:2]} but the labels "
                         f"are {data.labels.shape}; they must share the pixel grid")
    head = {**header, "irradiance_dtype": dtype, "irradiance_scale": scale,
            "label_meta": data.labels.meta, "meta": data.meta}
    arrays = {"irradiance": stored, "wavelengths_nm": np.asarray(data.wavelengths_nm, np.float64),
              "header_json": np.asarray(json.dumps(head, default=str)), **data.labels.to_arrays()}
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def read_frame(path: str | os.PathLike, irradiance: bool = True) -> tuple[FrameData, dict]:
    """Load a frame file: (FrameData with decoded irradiance, header dict). With
    irradiance=False only the labels are read (the irradiance is then an empty H×W×0 array)."""
    with np.load(path, allow_pickle=False) as z:
        keys = [k for k in z.files if irradiance or k != "irradiance"]
        arrays = {k: z[k] for k in keys}
    head = json.loads(str(arrays.pop("header_json")))
    if head.get("format") != FRAME_FORMAT:
        raise ValueError(f"{path}: not a workbench frame (format {head.get('format')!r})")
    labels = labels_from_arrays(arrays, head.get("label_meta"))
    irr = (decode_irradiance(arrays.pop("irradiance"), head["irradiance_scale"]) if irradiance
           else np.zeros((*labels.shape, 0), np.float32))
    return FrameData(irr, arrays["wavelengths_nm"], labels, head.get("meta", {})), head


def verify_frame(path: str | os.PathLike, fingerprint: str, index: int) -> bool:
    """True when the file is a complete, readable frame `index` of the data set `fingerprint`
    (every member decompresses with a good CRC and the header matches)."""
    try:
        data, head = read_frame(path)
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError):
        return False
    return (head.get("fingerprint") == fingerprint and head.get("index") == index
            and data.irradiance_photons.shape[:2] == data.labels.shape)


def code_version() -> str:
    """`git describe --always --dirty` of the source tree, else the package version."""
    from workbench import __version__
    root = Path(__file__).resolve().parents[2]
    try:
        out = subprocess.run(["git", "describe", "--always", "--dirty", "--tags"], cwd=root,
                             capture_output=True, text=True, timeout=10, check=False)
        if out.returncode == 0 and out.stdout.strip():
            return f"{__version__}+git.{out.stdout.strip()}"
    except (OSError, subprocess.SubprocessError):
        pass
    return __version__


# What a frame depends on: these project sections, and of the sensor only what sets the field of
# view and the wavelength range (exposure, noise, ISP and experiment settings do not matter).
FRAME_PROJECT_SECTIONS = ("seed", "scene", "city", "pose", "optics", "render")
FRAME_SENSOR_FIELDS = ("rows", "cols", "pixel_pitch_um", "cfa_pattern", "filter_file",
                       "photodiode_qe_file", "ir_cut_file")


def dataset_fingerprint(project, irradiance_dtype: str, renderer: Callable) -> str:
    """Digest of everything a frame depends on except its index (so sets can grow)."""
    doc = project.model_dump(mode="json")
    inputs = {k: doc.get(k) for k in FRAME_PROJECT_SECTIONS}
    inputs["sensor"] = {k: doc.get("sensor", {}).get(k) for k in FRAME_SENSOR_FIELDS}
    text = json.dumps({"inputs": inputs, "dtype": irradiance_dtype,
                       "renderer": f"{renderer.__module__}.{renderer.__qualname__}",
                       "frame_version": FRAME_VERSION}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def atomic_write_json(path: Path, obj) -> None:
    from workbench.project import atomic_write_text
    atomic_write_text(path, json.dumps(obj, indent=1, default=str) + "\n")


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
    every camera ray through the lens (mitsuba_camera, weight 'irradiance'), so the film holds
    sensor irradiance. The lens is prepared as formation/ prepares it and focused on
    optics.focus_distance_m or else scene.distance_m (the distance camera_hfov_deg focuses on);
    the sensor is cols × pixel pitch wide (or spans scene.fov_deg at the image distance), so the
    sample spacing is pixel pitch / oversample. Labels are cast through the lens camera (each
    pixel's ray through the centre of its exit-pupil box), so boxes follow the lens's distortion.
    render.shot_noise_ratio is resolved here: a pilot render through the optics and sensor gives
    the mean electrons N_e of the exposure, and the target error is ratio/√N_e."""
    from workbench.pipeline import camera_hfov_deg
    from workbench.render.labels import render_labels
    from workbench.render.scene_builder import build_scene, pinhole_sensor
    from workbench.render.spectral import drive, film_for, render_loaded
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
        from workbench.optics.lens.mitsuba_camera import full_model_camera, lens_sensor_dict
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
                                     lens_sensor, max_depth=project.render.max_depth)
    labels = render_labels(mi_scene, id_table, width, height)
    params = project.render.updated(seed=seeds.render)
    meta = {"variant": variant, "fov_deg": fov, "city_seed": recipe.seed, "arrangement": recipe.arrangement,
            "pose": {"position_m": np.asarray(pose.position_m).tolist(), "pan_deg": pose.pan_deg,
                     "tilt_deg": pose.tilt_deg, "roll_deg": pose.roll_deg,
                     "meta": getattr(pose, "meta", {})}}
    if camera is None:                  # the disc the directional sun cannot show
        from workbench.render.sun_disc import sun_disc
        disc = sun_disc(film, pose, fov, width, height, project.render.daylight, mi_scene=mi_scene)
        meta["sun_disc"] = disc.meta
    else:
        disc = None
        meta["sun_disc"] = {"status": "not composited: the full lens model bends the camera rays"}

    def with_sun(scene):
        if disc is not None:
            scene.radiance_photons = disc.add_to(scene.radiance_photons)
        return scene

    if params.shot_noise_ratio is not None:
        pilot = with_sun(drive(render_loaded(mi_scene, film, params.updated(spp=params.pilot_spp, shot_noise_ratio=None),
                                             fov_deg=fov, name=f"frame {seeds.index} pilot")))
        pilot.depth_m = labels.depth_m
        target = sensor_matched_error(project, CityRender(pilot, labels, camera, meta), params.shot_noise_ratio)
        meta["shot_noise_target_rel_error"] = target
        params = params.updated(shot_noise_ratio=None, target_rel_error=target)
    scene = with_sun(drive(render_loaded(mi_scene, film, params, fov_deg=fov, name=f"frame {seeds.index}"),
                           on_progress))
    scene.depth_m = labels.depth_m
    meta["spp"] = scene.meta.get("spp")
    meta["render"] = scene.meta
    return CityRender(scene, labels, camera, meta)


def sensor_matched_error(project, render: CityRender, shot_noise_ratio: float) -> float:
    """Relative render error that is `shot_noise_ratio` × the photon shot noise 1/√N_e, with N_e
    the mean electrons per pixel of the project's sensor at its exposure on this render."""
    from workbench.sensor import pixel_signal_rate, resolve_exposure
    rate = pixel_signal_rate(city_optical_image(render, project), project.sensor)
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
    from workbench.optics.lens.mitsuba_camera import full_model_optical_image
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


@dataclass(frozen=True)
class FrameJob:
    """Everything a worker needs to make and write one frame (picklable plain data)."""

    index: int
    seeds: FrameSeeds
    project: object
    path: str
    fingerprint: str
    irradiance_dtype: str
    renderer: Callable

    def __repr__(self) -> str:
        return f"FrameJob(index={self.index}, path={self.path!r})"


def run_frame_job(job: FrameJob) -> dict:
    """Worker function: render frame job.index and write it atomically; return a small record."""
    t0 = time.perf_counter()
    data = job.renderer(job.project, job.seeds)
    header = {"format": FRAME_FORMAT, "version": FRAME_VERSION, "index": job.index,
              "fingerprint": job.fingerprint, "seeds": asdict(job.seeds)}
    write_frame(job.path, data, header, job.irradiance_dtype)
    return {"index": job.index, "objects": len(data.labels.objects),
            "seconds": time.perf_counter() - t0}


@dataclass
class DatasetResult:
    out_dir: Path
    frames: int
    rendered: list[int]
    reused: list[int]
    manifest_path: Path
    coco_path: Path


def run_dataset(project, frames: int, out_dir: str | os.PathLike, *, workers: int = 1,
                cancel: CancelToken | None = None, irradiance_dtype: str = "float16",
                renderer: Callable | None = None,
                max_tasks_per_child: int | None = 16) -> Generator[Progress, None, DatasetResult]:
    """Render frames 0…frames−1 of `project` into out_dir (a long job: yields Progress).

    A rerun resumes: complete frames that verify are kept, half-written temporary files are
    removed, missing or damaged frames are rendered. coco.json and manifest.json are written
    when all frames exist. workers: processes (0 = in this process). renderer(project, seeds)
    -> FrameData makes one frame (module-level, picklable; default render_city_frame); irradiance_dtype: 'float16' or
    'float32' (error bounds in the module docstring). out_dir must not hold a set made from a
    different project or settings."""
    if not isinstance(frames, int) or frames < 1:
        raise ValueError(f"frames must be an integer ≥ 1, got {frames!r}")
    if irradiance_dtype not in IRRADIANCE_DTYPES:
        raise ValueError(f"irradiance_dtype '{irradiance_dtype}' not allowed; allowed: "
                         f"{', '.join(IRRADIANCE_DTYPES)}")
    renderer = renderer or render_city_frame
    out = Path(out_dir)
    (out / FRAMES_DIR).mkdir(parents=True, exist_ok=True)
    fingerprint = dataset_fingerprint(project, irradiance_dtype, renderer)
    spec_path = out / "dataset_spec.json"
    if spec_path.exists():
        old = json.loads(spec_path.read_text(encoding="utf-8")).get("fingerprint")
        if old != fingerprint:
            raise ValueError(f"{out} holds a data set made from a different project or settings "
                             f"(fingerprint {str(old)[:12]}… ≠ {fingerprint[:12]}…); choose another "
                             "output folder or delete that one")
    else:
        atomic_write_json(spec_path, {"format": DATASET_FORMAT, "fingerprint": fingerprint,
                                      "project": json.loads(project.model_dump_json()),
                                      "irradiance_dtype": irradiance_dtype})
    for tmp in (out / FRAMES_DIR).glob(".*.tmp"):
        tmp.unlink()                      # left by a run that was killed mid-write

    reused, todo = [], []
    for i in range(frames):
        if cancel is not None:
            cancel.check()
        path = frame_path(out, i)
        if path.exists() and verify_frame(path, fingerprint, i):
            reused.append(i)
        else:
            todo.append(FrameJob(i, frame_seeds(project.seed, i), project, str(path), fingerprint,
                                 irradiance_dtype, renderer))
        yield Progress(len(reused), frames, f"checked frame {i}")
    rendered = []
    for job, rec in run_jobs(run_frame_job, todo, workers, cancel,
                             max_tasks_per_child=max_tasks_per_child if workers else None):
        rendered.append(job.index)
        yield Progress(len(reused) + len(rendered), frames,
                       f"frame {job.index}: {rec['objects']} objects, {rec['seconds']:.1f} s")

    yield Progress(frames, frames, "writing coco.json and manifest.json")
    coco_frames, entries = [], []
    for i in range(frames):
        data, head = read_frame(frame_path(out, i), irradiance=False)
        rel = frame_path(out, i).relative_to(out).as_posix()
        coco_frames.append((rel, data.labels))
        entries.append({"index": i, "file": rel, "seeds": head["seeds"],
                        "objects": len(data.labels.objects), "meta": head.get("meta", {})})
    coco = labels_to_coco(coco_frames)
    for image, entry in zip(coco["images"], entries):
        image["frame_index"] = entry["index"]
    coco_path, manifest_path = out / "coco.json", out / "manifest.json"
    atomic_write_json(coco_path, coco)
    manifest = {
        "format": DATASET_FORMAT, "fingerprint": fingerprint, "frames": entries,
        "project": json.loads(project.model_dump_json()),
        "code_version": code_version(), "render": json.loads(project.render.model_dump_json()),
        "renderer": f"{renderer.__module__}.{renderer.__qualname__}",
        "seed_rule": "SeedSequence([project.seed, DATASET_SEED_TAG, index]).generate_state(3)",
        "irradiance": {"units": "photons/s/m^2/nm", "dtype": irradiance_dtype,
                       "max_rel_error": FLOAT16_REL_ERROR if irradiance_dtype == "float16" else 0.0,
                       "note": IRRADIANCE_NOTE},
        "coco": coco_path.name, "written_utc": datetime.now(timezone.utc).isoformat(),
    }
    atomic_write_json(manifest_path, manifest)
    return DatasetResult(out, frames, rendered, reused, manifest_path, coco_path)

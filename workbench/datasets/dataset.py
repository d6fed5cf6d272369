"""Resumable labelled data sets: N city frames rendered to irradiance + labels, COCO JSON, manifest.

Frame i is a pure function of the project and i: its seeds (city arrangement, camera pose, render
noise) come from numpy's SeedSequence([project.seed, DATASET_SEED_TAG, i]), so a set can be
extended, resumed or re-rendered frame by frame and gives the same bytes, on any compute backend.

Layout of out_dir:
  dataset_spec.json        what the frames were made from (project, storage); written first
  frames/frame_000007.npz  one frame, written whole or not at all (temporary name + os.replace) by
                           the driver process, whichever worker rendered it
  coco.json, manifest.json written (atomically) once every frame exists; removed when a run starts
                           with frames missing, so they never claim a frame that is not on disk;
                           the manifest records each frame's sha256, irradiance shape and scale
                           and its labels' digest, which readers check (datasets.integrity)
  .workbench.lock          held (flock) by the run writing the folder; a second run is refused

Irradiance storage: 'float16' keeps E / 2^k as float16 with the power of two 2^k chosen so that the
frame's maximum lies in (2^14, 2^15]; decoding multiplies exactly, so the only error is float16
rounding: relative error ≤ 2^-11 (0.049 %) for values above max · 2^-28 (3.7e-9 · max), absolute
error ≤ 2^-25 · 2^k below that. 'float32' stores the array as rendered (no error).
"""
from __future__ import annotations

import inspect
import io
import json
import os
import re
import subprocess
import time
import zipfile
from dataclasses import asdict, dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable, Generator

import numpy as np

from workbench.compute import ComputeSpec, report_progress, run_jobs
from workbench.compute.folder_lock import hold_folder_lock
from workbench.datasets.files import NPZ_ERRORS, check_npz, file_sha256, positive_finite, read_json_object
from workbench.datasets.stats import PLOT_NAME, STATS_NAME, write_statistics
from workbench.errors import InputFileError, InvalidValueError, OutputPathError, ParameterError
from workbench.files import atomic_write_bytes, parse_json
from workbench.jobs import CancelToken, Progress
from workbench.render import city_frame
from workbench.render.city_frame import FrameData, FrameSeeds, city_frame_inputs, render_city_frame
from workbench.render.labels import labels_from_arrays, labels_to_coco
from workbench.files import json_text

DATASET_FORMAT = "camera-workbench-dataset"
FRAME_FORMAT = "camera-workbench-frame"
FRAME_VERSION = 1
# Night frames only: 2 since the street lamps shine from under their heads (issue 33; they sat 0.13 m
# up, inside the pavement, before); 3 since head-lights are low beams (render/low_beam.py) instead of a
# symmetric cone; 4 since vehicle lights are seen glowing (render/lamp_heads.vehicle_light_faces). A
# separate tag, so day sets keep their fingerprints and results.
NIGHT_LIGHTS_VERSION = 4
# Frames of a city with a tunnel only: 1 since a black sheet under its floor stops rays falling
# through the kerb lines (scene_builder.tunnel_underlays) and, by day, it renders without Russian
# roulette (render/portal_guide.roulette_depth) and with its clear coats regularized for rays not
# from the camera (render/coat_regularization.py); untagged before. Other sets keep their fingerprints.
TUNNEL_VERSION = 1
IRRADIANCE_DTYPES = ("float16", "float32")
FLOAT16_REL_ERROR = 2.0 ** -11
FRAMES_DIR = "frames"
FRAME_NAME = re.compile(r"frame_(\d{6,})\.npz")
SPEC_NAME = "dataset_spec.json"
MAX_FRAMES = 1_000_000
ZIP_DATE = (1980, 1, 1, 0, 0, 0)       # member date in frame files (zip's earliest): same frame, same bytes
INTEGRITY_NOTE = ("frames[].sha256: sha256 of the frame file's bytes; irradiance_shape, irradiance_scale: "
                  "what its header and irradiance must hold; labels_sha256: sha256 of its coco.json image "
                  "and annotations as canonical JSON (sorted keys, separators ',' ':'); checked by readers "
                  "and `workbench dataset-verify`; categories_sha256: of coco.json's categories; "
                  "manifest_sha256: of this manifest without that field")
IRRADIANCE_NOTE = ("float16: E/2^k stored, 2^k puts the frame maximum in (2^14, 2^15]; relative error "
                   "<= 2^-11 above 2^-28 * max, absolute error <= 2^-25 * 2^k below; float32: exact")


def encode_irradiance(irradiance: np.ndarray, dtype: str) -> tuple[np.ndarray, float]:
    """(stored array, scale) with irradiance ≈ stored × scale (see the module docstring)."""
    if dtype not in IRRADIANCE_DTYPES:
        raise InvalidValueError(f"irradiance dtype '{dtype}' not allowed; allowed: {', '.join(IRRADIANCE_DTYPES)}")
    arr = np.asarray(irradiance, dtype=np.float32)
    if not np.all(np.isfinite(arr)) or (arr.size and arr.min() < 0):
        raise InvalidValueError("irradiance has NaN/Inf or negative values; refusing to store it")
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


def encode_frame(data: FrameData, header: dict, dtype: str) -> bytes:
    """The bytes of a frame file: an .npz (deflated zip) with fixed member dates, so the same frame
    gives the same bytes wherever and whenever it is made."""
    stored, scale = encode_irradiance(data.irradiance_photons, dtype)
    if stored.shape[:2] != data.labels.shape:
        raise InvalidValueError(f"frame {header.get('index')}: irradiance is {stored.shape[:2]} but the labels "
                         f"are {data.labels.shape}; they must share the pixel grid")
    head = {**header, "irradiance_dtype": dtype, "irradiance_scale": scale,
            "label_meta": data.labels.meta, "meta": data.meta}
    arrays = {"irradiance": stored, "wavelengths_nm": np.asarray(data.wavelengths_nm, np.float64),
              "header_json": np.asarray(json.dumps(head, default=str)), **data.labels.to_arrays()}
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, arr in arrays.items():
            info = zipfile.ZipInfo(f"{name}.npy", date_time=ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            with zf.open(info, "w", force_zip64=True) as fh:
                np.lib.format.write_array(fh, np.asanyarray(arr), allow_pickle=False)
    return buf.getvalue()


def write_frame(path: str | os.PathLike, data: FrameData, header: dict, dtype: str) -> None:
    """Write one frame atomically (encode_frame, then files.atomic_write_bytes)."""
    atomic_write_bytes(path, encode_frame(data, header, dtype))


def read_frame(path: str | os.PathLike, irradiance: bool = True) -> tuple[FrameData, dict]:
    """Load a frame file: (FrameData with decoded irradiance, header dict). With
    irradiance=False only the labels are read (the irradiance is then an empty H×W×0 array).
    The members' sizes are checked from their headers before any array is read
    (datasets.files.check_npz); a file that is no frame, an irradiance that is not H×W×bands on
    the labels' pixel grid, an irradiance_scale that is not a finite number > 0, or (when read)
    irradiance with NaN/Inf or negative values is an InputFileError naming the file."""
    members = check_npz(path)
    if "header_json" not in members or "irradiance" not in members:
        raise InputFileError(path, "lacks a frame's members (header_json, irradiance): not a workbench frame")
    shape, dtype = members["irradiance"]
    bands = members.get("wavelengths_nm", ((),))[0]
    if len(shape) != 3 or dtype.name not in IRRADIANCE_DTYPES or bands != shape[2:]:
        raise InputFileError(path, f"its irradiance is a {shape} {dtype.name} array with wavelengths {bands}; a "
                                   f"frame's is H×W×bands, {' or '.join(IRRADIANCE_DTYPES)}, one wavelength a band")
    try:
        with np.load(path, allow_pickle=False) as z:
            keys = [k for k in z.files if irradiance or k != "irradiance"]
            arrays = {k: z[k] for k in keys}
        head = parse_json(str(arrays.pop("header_json")), path, "frame header")
        if not isinstance(head, dict) or head.get("format") != FRAME_FORMAT:
            raise InputFileError(path, "its header is not a workbench frame's")
        labels = labels_from_arrays(arrays, head.get("label_meta"))
    except InputFileError:
        raise
    except (*NPZ_ERRORS, KeyError, IndexError, TypeError) as exc:
        raise InputFileError(path, f"cannot be read as a frame ({type(exc).__name__}): damaged or not a "
                                   "workbench frame") from None
    grids = {np.shape(getattr(labels, k)) for k in ("depth_m", "planar_depth_m", "class_id", "instance_id")}
    if grids != {shape[:2]}:
        raise InputFileError(path, f"its irradiance is {shape[0]}×{shape[1]} px but its label maps are "
                                   f"{' / '.join(sorted('×'.join(map(str, g)) for g in grids))}: they must share one "
                                   "pixel grid")
    scale = head.get("irradiance_scale")
    if not positive_finite(scale):
        raise InputFileError(path, f"its header's irradiance_scale ({str(scale)[:20]!r}) must be a finite number > 0")
    if not irradiance:
        return FrameData(np.zeros((*labels.shape, 0), np.float32), arrays["wavelengths_nm"], labels,
                         head.get("meta", {})), head
    with np.errstate(over="ignore", invalid="ignore"):      # an overflow is counted and refused below
        irr = decode_irradiance(arrays.pop("irradiance"), scale)
    bad = irr.size - np.count_nonzero(np.isfinite(irr) & (irr >= 0))
    if bad:
        raise InputFileError(path, f"its irradiance holds {bad:,} NaN, infinite or negative value(s); a frame "
                                   "holds finite irradiance ≥ 0")
    return FrameData(irr, arrays["wavelengths_nm"], labels, head.get("meta", {})), head


def verify_frame(path: str | os.PathLike, fingerprint: str, index: int) -> bool:
    """True when the file is a complete, readable frame `index` of the data set `fingerprint`
    (every member decompresses with a good CRC, the header matches and read_frame's checks of
    the irradiance and labels pass)."""
    try:
        data, head = read_frame(path)
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError):
        return False
    return (head.get("fingerprint") == fingerprint and head.get("index") == index
            and data.irradiance_photons.shape[:2] == data.labels.shape)


CODE_PATHS = ("workbench", "resources", "pyproject.toml")   # what a run's results depend on


def code_version(root: Path | None = None) -> str:
    """`git describe --always --tags` of the source tree (root: this checkout), '-dirty' when the
    code (CODE_PATHS, not the results folders a running experiment rewrites) differs from it; else
    the package version."""
    from workbench import __version__
    root = root or Path(__file__).resolve().parents[2]
    try:
        out = subprocess.run(["git", "describe", "--always", "--tags"], cwd=root,
                             capture_output=True, text=True, timeout=10, check=False)
        changed = subprocess.run(["git", "status", "--porcelain", "--", *CODE_PATHS], cwd=root,
                                 capture_output=True, text=True, timeout=10, check=False)
        if out.returncode == 0 and out.stdout.strip() and changed.returncode == 0:
            return f"{__version__}+git.{out.stdout.strip()}" + ("-dirty" if changed.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        pass
    return __version__


def dataset_fingerprint(project, irradiance_dtype: str, renderer: Callable) -> str:
    """Digest of everything a frame reads (city_frame.city_frame_inputs: the render's inputs, the
    optics and the illuminance adjustment) except its index, so sets can grow."""
    from workbench.stages.keys import digest
    tags = (NIGHT_LIGHTS_VERSION,) if project.render.world.lighting == "night" else ()
    tags += ("tunnel", TUNNEL_VERSION) if project.city is not None and project.city.tunnel else ()
    return digest(city_frame_inputs(project), irradiance_dtype, f"{renderer.__module__}.{renderer.__qualname__}",
                  FRAME_VERSION, *tags)


def atomic_write_json(path: Path, obj) -> None:
    from workbench.files import atomic_write_text
    atomic_write_text(path, json_text(obj, default=str) + "\n")


@dataclass(frozen=True)
class CityJob:
    """Everything a worker needs to make the missing frames of one city arrangement (picklable
    plain data): they render one after the other through one CitySceneSession, so the city is
    built and loaded once."""

    seeds: tuple[FrameSeeds, ...]
    project: object
    fingerprint: str
    irradiance_dtype: str
    renderer: Callable

    @property
    def indices(self) -> list[int]:
        return [s.index for s in self.seeds]

    def __repr__(self) -> str:
        first, last = self.seeds[0].index, self.seeds[-1].index
        return f"frame {first}" if first == last else f"frames {first}–{last} (city {self.seeds[0].city})"


@dataclass(frozen=True)
class FramePayload:
    """A rendered frame on its way to the driver: the frame file's bytes and a small record."""

    index: int
    payload: bytes
    objects: int
    seconds: float


def render_city_job(job: CityJob) -> list[FramePayload]:
    """Worker function: render the frames of job and encode their files (the driver writes them).
    A renderer that takes `session` gets one CitySceneSession for all of them; one that takes
    on_progress reports the job's progress (frames done + this frame's fraction) to the driver."""
    from workbench.render.city_frame import CitySceneSession
    params = inspect.signature(job.renderer).parameters
    session = CitySceneSession() if "session" in params else None
    out = []
    for k, seeds in enumerate(job.seeds):
        t0 = time.perf_counter()
        kwargs = {"session": session} if session is not None else {}
        if "on_progress" in params:
            kwargs["on_progress"] = lambda step, k=k: report_progress(k + step.done / step.total, len(job.seeds))
        data = job.renderer(job.project, seeds, **kwargs)
        header = {"format": FRAME_FORMAT, "version": FRAME_VERSION, "index": seeds.index,
                  "fingerprint": job.fingerprint, "seeds": asdict(seeds)}
        payload = encode_frame(data, header, job.irradiance_dtype)
        out.append(FramePayload(seeds.index, payload, len(data.labels.objects), time.perf_counter() - t0))
    return out


def _frame_in_flight(job: CityJob, done: float) -> str:
    """'frame I P %': the frame a city job is rendering, `done` frames into it."""
    k = min(int(done), len(job.seeds) - 1)
    return f"frame {job.seeds[k].index} {100 * (done - k):.0f} %"


def city_jobs(project, frames: int, done: set[int], fingerprint: str, irradiance_dtype: str,
              renderer: Callable):
    """The CityJobs of the frames < `frames` not in `done`, city by city in order (lazily)."""
    from workbench.render.city_frame import project_frame_seeds
    per_city = project.pose.poses_per_arrangement if project.pose is not None else 1
    for first in range(0, frames, per_city):
        todo = tuple(project_frame_seeds(project, i) for i in range(first, min(first + per_city, frames))
                     if i not in done)
        if todo:
            yield CityJob(todo, project, fingerprint, irradiance_dtype, renderer)


def _steps(step) -> tuple[float, float]:
    """(done, total) of a renderer's Progress step."""
    return step.done, step.total


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
                renderer: Callable | None = None, max_tasks_per_child: int | None = 16,
                compute: ComputeSpec | None = None) -> Generator[Progress, None, DatasetResult]:
    """Render frames 0…frames−1 of `project` into out_dir (a long job: yields Progress).

    A rerun resumes: complete frames that verify (and whose bytes are those the folder's last
    manifest recorded, if any) are kept, half-written temporary files are removed, missing or
    damaged frames are rendered. coco.json and manifest.json are written
    when all frames exist. Where frames render: `compute` (any backend), else `workers` local
    processes (0 = in this process); whichever renders a frame, this process alone writes it
    (atomically), under a lock on out_dir that a second run is refused. renderer(project, seeds)
    -> FrameData makes one frame (module-level, picklable; default render_city_frame); irradiance_dtype: 'float16' or
    'float32' (error bounds in the module docstring). out_dir must not hold a set made from a
    different project or settings. Frames are planned lazily; at most MAX_FRAMES."""
    if isinstance(frames, bool) or not isinstance(frames, int) or not 1 <= frames <= MAX_FRAMES:
        raise ParameterError("frames", frames, f"an integer from 1 to {MAX_FRAMES:,}")
    if irradiance_dtype not in IRRADIANCE_DTYPES:
        raise ParameterError("irradiance_dtype", irradiance_dtype, f"one of {', '.join(IRRADIANCE_DTYPES)}")
    renderer = renderer or render_city_frame
    if renderer is city_frame.render_city_frame and project.scene.kind != "city":   # before the folder is made
        raise ParameterError("scene.kind", project.scene.kind, "'city': a data set is rendered city frames "
                             "(choose a city project, e.g. city_detection_quick)")
    compute = compute or ComputeSpec(workers=workers,
                                     max_tasks_per_child=max_tasks_per_child if workers else None)
    out = prepare_out_dir(out_dir)
    fingerprint = dataset_fingerprint(project, irradiance_dtype, renderer)
    with hold_folder_lock(out, "workbench dataset"):
        check_spec(out, fingerprint, project, irradiance_dtype)
        for tmp in (out / FRAMES_DIR).glob(".*.tmp"):
            tmp.unlink()                      # left by a run that was killed mid-write
        found, odd = scan_frames(out, frames)
        recorded = recorded_hashes(out, fingerprint)
        if odd or len(found) < frames:
            remove_index(out)
        if odd:
            raise OutputPathError(odd[0], "is not a regular file but has a frame's name; remove it "
                                          "and run again")
        reused = []
        for i in found:
            if cancel is not None:
                cancel.check()
            path = frame_path(out, i)
            if verify_frame(path, fingerprint, i) and (i not in recorded or recorded[i] == file_sha256(path)):
                reused.append(i)
            yield Progress(len(reused), frames, f"checked frame {i}")
        if len(reused) < frames:
            remove_index(out)
        todo = city_jobs(project, frames, set(reused), fingerprint, irradiance_dtype, renderer)
        rendered, running = [], {}
        for item in run_jobs(render_city_job, todo, compute, cancel, task_progress=True):
            if isinstance(item, Progress):          # a city still rendering: its frames done so far
                job = item.source
                running[job.seeds[0].city] = (job, item.done)
                yield Progress(len(reused) + len(rendered) + sum(d for _, d in running.values()), frames,
                               "rendering " + ", ".join(_frame_in_flight(j, d) for j, d in
                                                        (running[c] for c in sorted(running))))
                continue
            job, records = item
            running.pop(job.seeds[0].city, None)
            for rec in records:
                atomic_write_bytes(frame_path(out, rec.index), rec.payload)
                rendered.append(rec.index)
                yield Progress(len(reused) + len(rendered) + sum(d for _, d in running.values()), frames,
                               f"frame {rec.index}: {rec.objects} objects, {rec.seconds:.1f} s")
        result = yield from write_index(out, project, frames, fingerprint, irradiance_dtype, renderer)
    return DatasetResult(out, frames, rendered, reused, *result)


def prepare_out_dir(out_dir: str | os.PathLike) -> Path:
    """out_dir as a Path, with its frames folder made; OutputPathError when it cannot be."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise OutputPathError(out, "is a file, not a folder; give a folder for the data set")
    try:
        (out / FRAMES_DIR).mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise OutputPathError(out / FRAMES_DIR, "exists and is not a folder") from None
    except OSError as exc:
        raise OutputPathError(out, f"cannot make the data-set folder ({exc.strerror or exc})") from None
    return out


def check_spec(out: Path, fingerprint: str, project, irradiance_dtype: str) -> None:
    """Write dataset_spec.json, or check that the one there describes the same data set."""
    spec_path = out / SPEC_NAME
    if not spec_path.exists():
        atomic_write_json(spec_path, {"format": DATASET_FORMAT, "fingerprint": fingerprint,
                                      "project": json.loads(project.model_dump_json()),
                                      "irradiance_dtype": irradiance_dtype})
        return
    spec = read_json_object(spec_path, "data-set spec", "")
    old = spec.get("fingerprint")
    if old != fingerprint:
        raise OutputPathError(out, f"holds a data set made from {spec_differences(spec, project)} "
                                   f"(fingerprint {str(old)[:12]}… ≠ {fingerprint[:12]}…); choose another "
                                   "output folder or delete that one")


def spec_differences(spec: dict, project) -> str:
    """Why a stored data-set spec does not match `project`, in words: the frame inputs that differ
    (down to the fields), or that the settings are the same but the frame code has changed since."""
    from pydantic import ValidationError

    from workbench.render.city_frame import frame_input_differences
    try:
        stored = type(project).model_validate(spec.get("project"))     # as written by this schema version
    except (ValidationError, ValueError, TypeError):
        return "a different project or settings (its stored project no longer loads)"
    if not frame_input_differences(stored, project):
        return ("the same settings by an earlier version of the frame renderer (frame format "
                f"{FRAME_VERSION} or its code changed since): its frames cannot be mixed with new ones")
    from workbench.project import project_differences
    fields = [f for f, _, _ in project_differences(stored, project, skip=("name", "description", "experiment"))]
    return "a different project or settings (" + ", ".join(fields[:8]) + (" …" if len(fields) > 8 else "") + ")"


def scan_frames(out: Path, frames: int) -> tuple[list[int], list[str]]:
    """(sorted indices < frames with a regular frame file, paths with a frame's name that are not
    regular files): one directory scan, not one look-up per planned frame."""
    found, odd = [], []
    with os.scandir(out / FRAMES_DIR) as it:
        for entry in it:
            m = FRAME_NAME.fullmatch(entry.name)
            if m is None or int(m.group(1)) >= frames:
                continue
            if entry.is_file(follow_symlinks=False):
                found.append(int(m.group(1)))
            else:
                odd.append(entry.path)
    return sorted(found), sorted(odd)


def remove_index(out: Path) -> None:
    """Remove coco.json, manifest.json and the statistics: they must never claim a frame that is
    not on disk."""
    for name in ("coco.json", "manifest.json", STATS_NAME, PLOT_NAME):
        (out / name).unlink(missing_ok=True)


def write_index(out: Path, project, frames: int, fingerprint: str, irradiance_dtype: str, renderer):
    """Write coco.json, manifest.json and the statistics (datasets.stats) from the frames on disk
    (a job step: yields Progress). Each manifest entry records what a reader checks the frame
    against (datasets.integrity): the sha256 of its bytes, its irradiance shape and scale, and
    the digest of its labels in coco.json."""
    from workbench.datasets.files import json_digest, labels_digest, manifest_digest
    from workbench.files import atomic_write_text
    yield Progress(frames, frames, "writing coco.json, manifest.json and statistics")
    coco_frames, entries = [], []
    for i in range(frames):
        path = frame_path(out, i)
        if not path.is_file() or path.is_symlink():
            raise OutputPathError(path, "frame missing or not a regular file (changed during the run); "
                                        "run again to render it")
        data, head = read_frame(path, irradiance=False)
        rel = frame_path(out, i).relative_to(out).as_posix()
        coco_frames.append((rel, data.labels))
        entries.append({"index": i, "file": rel, "seeds": head["seeds"],
                        "objects": len(data.labels.objects), "meta": head.get("meta", {}),
                        "sha256": file_sha256(path), "irradiance_shape": list(check_npz(path)["irradiance"][0]),
                        "irradiance_scale": head["irradiance_scale"]})
    coco = labels_to_coco(coco_frames)
    for image, entry in zip(coco["images"], entries):
        image["frame_index"] = entry["index"]
    coco_text = json.dumps(coco, indent=1, default=str) + "\n"
    written = json.loads(coco_text)                 # the labels as a reader will see them
    anns: dict[int, list] = {}
    for a in written["annotations"]:
        anns.setdefault(a["image_id"], []).append(a)
    for image, entry in zip(written["images"], entries):
        entry["labels_sha256"] = labels_digest(image, anns.get(image["id"], []))
    coco_path, manifest_path = out / "coco.json", out / "manifest.json"
    atomic_write_text(coco_path, coco_text)
    manifest = {
        "format": DATASET_FORMAT, "fingerprint": fingerprint, "frames": entries,
        "project": json.loads(project.model_dump_json()),
        "code_version": code_version(), "render": json.loads(project.render.model_dump_json()),
        "renderer": f"{renderer.__module__}.{renderer.__qualname__}",
        "seed_rule": "SeedSequence([project.seed, DATASET_SEED_TAG, index]).generate_state(3)",
        "irradiance": {"units": "photons/s/m^2/nm", "dtype": irradiance_dtype,
                       "max_rel_error": FLOAT16_REL_ERROR if irradiance_dtype == "float16" else 0.0,
                       "note": IRRADIANCE_NOTE},
        "integrity": INTEGRITY_NOTE, "categories_sha256": json_digest(written["categories"]),
        "coco": coco_path.name, "written_utc": datetime.now(timezone.utc).isoformat(),
    }
    manifest = json.loads(json.dumps(manifest, default=str))      # as a reader will see it
    manifest["manifest_sha256"] = manifest_digest(manifest)
    write_statistics(out, [labels for _, labels in coco_frames])
    atomic_write_json(manifest_path, manifest)
    return manifest_path, coco_path


def recorded_hashes(out: Path, fingerprint: str) -> dict[int, str]:
    """Frame index → sha256 as the folder's manifest.json recorded them (empty when there is no
    readable manifest of this data set): a resume re-renders a frame whose bytes changed since."""
    try:
        manifest = read_json_object(out / "manifest.json", "data-set manifest", "")
    except InputFileError:
        return {}
    frames = manifest.get("frames") if manifest.get("fingerprint") == fingerprint else None
    return {e["index"]: e["sha256"] for e in frames if isinstance(e, dict) and isinstance(e.get("index"), int)
            and isinstance(e.get("sha256"), str)} if isinstance(frames, list) else {}


def write_folder_statistics(out_dir: str | os.PathLike) -> tuple[Path, Path]:
    """Write statistics.json and statistics.png of the frames now in a data-set folder (finished or
    not); InputFileError when the folder has no frames folder, or an entry with a frame's name is
    not a regular file (a FIFO, a link) or cannot be read as a frame; OutputPathError while another
    command (a render) holds the folder's lock."""
    out = Path(out_dir)
    if not out.is_dir():
        raise InputFileError(out, "does not exist or is not a folder; give a data-set folder")
    if not (out / FRAMES_DIR).is_dir():
        raise InputFileError(out, f"is not a data-set folder (no {FRAMES_DIR}/ folder in it)")
    with hold_folder_lock(out, "workbench dataset-stats"):      # refused while a render writes the folder
        return write_statistics(out, _folder_labels(out))


def _folder_labels(out: Path) -> list:
    """The labels of every frame file in a data-set folder (InputFileError naming a bad one)."""
    labels = []
    for path in sorted((out / FRAMES_DIR).iterdir()):
        if not FRAME_NAME.fullmatch(path.name):
            continue
        if path.is_symlink() or not path.is_file():
            raise InputFileError(path, "has a frame's name but is not a regular file (a link, FIFO or device); "
                                       "remove it, or render the frame with `workbench dataset PROJECT --frames N "
                                       f"--out {out}`")
        labels.append(read_frame(path, irradiance=False)[0].labels)
    return labels

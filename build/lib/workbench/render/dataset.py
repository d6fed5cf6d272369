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
from dataclasses import asdict, dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable, Generator

import numpy as np

from workbench.compute.local import run_jobs
from workbench.jobs import CancelToken, Progress
from workbench.render.city_frame import FrameData, FrameSeeds, frame_seeds, render_city_frame
from workbench.render.labels import labels_from_arrays, labels_to_coco

DATASET_FORMAT = "camera-workbench-dataset"
FRAME_FORMAT = "camera-workbench-frame"
FRAME_VERSION = 1
IRRADIANCE_DTYPES = ("float16", "float32")
FLOAT16_REL_ERROR = 2.0 ** -11
FRAMES_DIR = "frames"
IRRADIANCE_NOTE = ("float16: E/2^k stored, 2^k puts the frame maximum in (2^14, 2^15]; relative error "
                   "<= 2^-11 above 2^-28 * max, absolute error <= 2^-25 * 2^k below; float32: exact")


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

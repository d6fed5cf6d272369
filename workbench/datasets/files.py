"""Reading the files of a data-set or results folder as untrusted input, one way for all of them.

A folder someone hands over may hold anything: JSON nested thousands deep, a field of the wrong
type, a manifest that lists a frame twice or a path outside the folder, an `.npz` whose header
declares a billion-element array. Every reader here refuses such a file with an InputFileError
that names it, before using or allocating anything:

    read_json_object  size ≤ max_bytes, UTF-8, JSON depth and duplicate keys (files.parse_json), an
                      object at the top
    manifest_frames   the manifest's frame list: integer indices and seeds, each index and file
                      once, every file a `frames/frame_NNNNNN.npz` inside the folder, and what the
                      frame must be (FrameEntry: its sha256, irradiance shape and scale, the
                      digest of its labels in coco.json)
    coco_tables       coco.json's categories, images and annotations, with types and finite,
                      non-negative boxes, each image id and frame index once
    inside            a path named by a file, confined to the folder
    check_npz         an .npz's members, shapes and dtypes from their headers, within a byte budget
    file_sha256       the sha256 of a regular file's bytes, read in blocks

A FIFO, a device or a link to one is refused by check_npz and file_sha256 before it is opened
(opening a FIFO waits for a writer; /dev/zero never ends).
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import re
import stat
import tokenize
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from workbench.errors import InputFileError
from workbench.files import parse_json, read_text

MAX_JSON_BYTES = 512 * 2 ** 20          # coco.json of a million frames stays below this
MAX_NPZ_MEMBER_BYTES = 2 * 2 ** 30      # no frame array is larger (a 8192² × 8 float32 film)
FRAME_FILE = "frames/frame_{:06d}.npz"
SEED_KEYS = ("index", "arrangement", "pose", "render")
OPTIONAL_SEED_KEYS = ("city",)          # the city arrangement a frame's pose belongs to (the split's unit);
                                        # frames written before cities were numbered lack it
SHA256_HEX = re.compile(r"[0-9a-f]{64}")
# What zipfile, zlib and numpy raise on a damaged .npz (numpy tokenizes a damaged 1.0 array header).
NPZ_ERRORS = (zipfile.BadZipFile, ValueError, OSError, EOFError, zlib.error, tokenize.TokenError)


@dataclass(frozen=True)
class FrameEntry:
    """One frame as manifest.json lists it: index, file, seeds, and what the file must hold: the
    sha256 of its bytes, its irradiance array's shape (H, W, bands) and scale, and the sha256 of
    its image record and annotations in coco.json (datasets.integrity.labels_digest)."""

    index: int
    path: Path
    seeds: dict
    sha256: str
    irradiance_shape: tuple[int, int, int]
    irradiance_scale: float
    labels_sha256: str


def read_json_object(path: str | Path, what: str, missing_hint: str, max_bytes: int = MAX_JSON_BYTES) -> dict:
    """A JSON object from a file of a data-set or results folder (module docstring)."""
    p = Path(path)
    if not p.exists():
        raise InputFileError(p, f"missing: {missing_hint}")
    data = parse_json(read_text(p, what, max_bytes), p, what)
    if not isinstance(data, dict):
        raise InputFileError(p, f"holds a JSON {type(data).__name__}, not the object a {what} is")
    return data


def _int(value, path: Path, where: str, low: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise InputFileError(path, f"{where} must be an integer ≥ {low}")
    return value


def inside(folder: Path, name: object, path: Path, where: str) -> Path:
    """folder / name, refused unless name is a relative path that stays inside the folder."""
    if not isinstance(name, str) or not name or len(name) > 255:
        raise InputFileError(path, f"{where} must be a file name inside the folder")
    target = (folder / name).resolve()
    if Path(name).is_absolute() or not target.is_relative_to(folder.resolve()):
        raise InputFileError(path, f"{where} names a file outside the data-set folder; refused")
    return folder / name


def manifest_frames(manifest: dict, folder: Path, path: Path) -> list[FrameEntry]:
    """Every frame a manifest lists, checked (module docstring)."""
    frames = manifest.get("frames")
    if not isinstance(frames, list) or not frames:
        raise InputFileError(path, "'frames' must be a non-empty list of frame entries")
    out, seen = [], set()
    for k, entry in enumerate(frames):
        where = f"frames[{k}]"
        if not isinstance(entry, dict):
            raise InputFileError(path, f"{where} must be an object")
        index = _int(entry.get("index"), path, f"{where}.index")
        if index in seen:
            raise InputFileError(path, f"{where}: frame {index} is listed twice; a data set holds each frame once")
        seen.add(index)
        if entry.get("file") != FRAME_FILE.format(index):
            raise InputFileError(path, f"{where}.file must be {FRAME_FILE.format(index)!r} (frames are named by index)")
        seeds = entry.get("seeds")
        if not isinstance(seeds, dict):
            raise InputFileError(path, f"{where}.seeds must be an object")
        seeds = {**{key: _int(seeds.get(key), path, f"{where}.seeds.{key}") for key in SEED_KEYS},
                 **{key: _int(seeds[key], path, f"{where}.seeds.{key}") for key in OPTIONAL_SEED_KEYS if key in seeds}}
        for key in ("sha256", "labels_sha256"):
            if not isinstance(entry.get(key), str) or not SHA256_HEX.fullmatch(entry[key]):
                raise InputFileError(path, f"{where}.{key} must be 64 lower-case hex digits (a sha256)")
        shape = entry.get("irradiance_shape")
        if not isinstance(shape, list) or len(shape) != 3:
            raise InputFileError(path, f"{where}.irradiance_shape must be [H, W, bands]")
        shape = tuple(_int(v, path, f"{where}.irradiance_shape", low=1) for v in shape)
        scale = entry.get("irradiance_scale")
        if not positive_finite(scale):
            raise InputFileError(path, f"{where}.irradiance_scale must be a finite number > 0")
        out.append(FrameEntry(index, inside(folder, entry["file"], path, f"{where}.file"), seeds,
                              entry["sha256"], shape, float(scale), entry["labels_sha256"]))
    return out


def positive_finite(value) -> bool:
    """True for an int or float (not a bool) that is finite and > 0."""
    return (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
            and value > 0)


def _finite_list(value, n: int) -> bool:
    return (isinstance(value, list) and len(value) == n
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value))


def coco_tables(coco: dict, path: Path) -> tuple[dict[int, str], dict[int, dict], dict[int, list[dict]]]:
    """(category id → name, frame index → image, image id → annotations) of a coco.json, checked:
    every field the detection data reads has its type, boxes are finite with w, h ≥ 0, and each
    image id and frame index appears once."""
    tables = {key: coco.get(key) for key in ("categories", "images", "annotations")}
    for key, value in tables.items():
        if not isinstance(value, list):
            raise InputFileError(path, f"'{key}' must be a list")
    names: dict[int, str] = {}
    for k, c in enumerate(tables["categories"]):
        if not isinstance(c, dict) or not isinstance(c.get("name"), str):
            raise InputFileError(path, f"categories[{k}] must be an object with an integer id and a name")
        names[_int(c.get("id"), path, f"categories[{k}].id")] = c["name"]
    images, ids = {}, set()
    for k, im in enumerate(tables["images"]):
        if not isinstance(im, dict):
            raise InputFileError(path, f"images[{k}] must be an object")
        image_id = _int(im.get("id"), path, f"images[{k}].id")
        frame = _int(im.get("frame_index"), path, f"images[{k}].frame_index")
        for key in ("width", "height"):
            _int(im.get(key), path, f"images[{k}].{key}", low=1)
        if image_id in ids or frame in images:
            raise InputFileError(path, f"images[{k}]: image {image_id} / frame {frame} is listed twice")
        ids.add(image_id)
        images[frame] = im
    anns: dict[int, list[dict]] = {}
    for k, a in enumerate(tables["annotations"]):
        where = f"annotations[{k}]"
        if not isinstance(a, dict):
            raise InputFileError(path, f"{where} must be an object")
        image_id = _int(a.get("image_id"), path, f"{where}.image_id")
        _int(a.get("category_id"), path, f"{where}.category_id")
        if not _finite_list(a.get("bbox"), 4) or a["bbox"][2] < 0 or a["bbox"][3] < 0:
            raise InputFileError(path, f"{where}.bbox must be four finite numbers x, y, w ≥ 0, h ≥ 0")
        for key in ("occlusion", "truncation"):
            value = a.get(key, 0.0)
            if not _finite_list([value], 1) or not 0.0 <= value <= 1.0:
                raise InputFileError(path, f"{where}.{key} must be a number in 0…1")
        anns.setdefault(image_id, []).append(a)
    return names, images, anns


def check_npz(path: str | Path, max_member_bytes: int = MAX_NPZ_MEMBER_BYTES) -> dict[str, tuple[tuple, np.dtype]]:
    """Shape and dtype of every array of an .npz, read from the member headers without loading
    an array; InputFileError for a member that is not a plain .npy array (objects, pickles) or
    that would take more than max_member_bytes."""
    p = Path(path)
    regular_file(p, "an .npz")
    out = {}
    try:
        with zipfile.ZipFile(p) as zf:
            for info in zf.infolist():
                name = info.filename
                if not name.endswith(".npy"):
                    raise InputFileError(p, f"holds a member that is not an array ({name[:40]!r})")
                with zf.open(info) as fh:
                    version = np.lib.format.read_magic(fh)
                    shape, _, dtype = (np.lib.format.read_array_header_1_0(fh) if version == (1, 0)
                                       else np.lib.format.read_array_header_2_0(fh))
                if dtype.hasobject:
                    raise InputFileError(p, f"member {name[:40]!r} holds Python objects; refused")
                size = int(np.prod(shape, dtype=np.float64)) * dtype.itemsize
                if size > max_member_bytes:
                    raise InputFileError(p, f"member {name[:40]!r} declares {size:,} bytes (more than "
                                            f"{max_member_bytes:,}); not a frame this workbench wrote")
                out[name[:-4]] = (tuple(shape), dtype)
    except InputFileError:
        raise
    except NPZ_ERRORS as exc:
        raise InputFileError(p, f"cannot be read as an .npz ({type(exc).__name__}); damaged or not a frame") from None
    return out


def regular_file(path: Path, what: str) -> os.stat_result:
    """The stat of path (links followed) when it is a regular file, else an InputFileError:
    checked before opening, as a FIFO would block and a device never end."""
    try:
        st = os.stat(path)
    except OSError as exc:
        raise InputFileError(path, f"cannot be read ({exc.strerror or type(exc).__name__})") from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a folder" if stat.S_ISDIR(st.st_mode) else "a FIFO" if stat.S_ISFIFO(st.st_mode) else \
            "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else "not a regular file"
        raise InputFileError(path, f"is {kind}, not {what} file; refused without reading it")
    return st


def file_sha256(path: str | Path) -> str:
    """Hex sha256 of a regular file's bytes (read in blocks, so any size fits in memory)."""
    p = Path(path)
    regular_file(p, "a data-set")
    try:
        with open(p, "rb") as fh:
            return hashlib.file_digest(fh, "sha256").hexdigest()
    except OSError as exc:
        raise InputFileError(p, f"cannot be read ({exc.strerror or type(exc).__name__})") from None


def json_digest(value) -> str:
    """sha256 of a decoded JSON value as canonical JSON (sorted keys, no spaces)."""
    text = json.dumps(value, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()


def labels_digest(image: dict, annotations: list[dict]) -> str:
    """sha256 of a frame's coco.json image record and annotations (json_digest)."""
    return json_digest([image, annotations])


def manifest_digest(manifest: dict) -> str:
    """sha256 of a manifest's content, its own manifest_sha256 left out (json_digest)."""
    return json_digest({k: v for k, v in manifest.items() if k != "manifest_sha256"})

"""Reading the files of a data-set or results folder as untrusted input, one way for all of them.

A folder someone hands over may hold anything: JSON nested thousands deep, a field of the wrong
type, a manifest that lists a frame twice or a path outside the folder, an `.npz` whose header
declares a billion-element array. Every reader here refuses such a file with an InputFileError
that names it, before using or allocating anything:

    read_json_object  size ≤ max_bytes, UTF-8, JSON depth and duplicate keys (files.parse_json), an
                      object at the top
    manifest_frames   the manifest's frame list: integer indices and seeds, each index and file
                      once, every file a `frames/frame_NNNNNN.npz` inside the folder
    coco_tables       coco.json's categories, images and annotations, with types and finite,
                      non-negative boxes, each image id and frame index once
    inside            a path named by a file, confined to the folder
    check_npz         an .npz's members, shapes and dtypes from their headers, within a byte budget
"""
from __future__ import annotations

import math
import zipfile
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


def manifest_frames(manifest: dict, folder: Path, path: Path) -> list[tuple[int, Path, dict]]:
    """(index, frame file, seeds) of every frame a manifest lists, checked (module docstring)."""
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
        out.append((index, inside(folder, entry["file"], path, f"{where}.file"), seeds))
    return out


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
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
        raise InputFileError(p, f"cannot be read as an .npz ({type(exc).__name__}); damaged or not a frame") from None
    return out

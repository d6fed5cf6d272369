"""A data set verifies itself: what manifest.json records of each frame, checked when the set is
opened and when a frame is first read, and every check at once (`workbench dataset-verify`).

Recorded per frame when the index is written (datasets.dataset.write_index): the sha256 of the
frame file's bytes, its irradiance shape (H, W, bands) and scale, and labels_sha256, the sha256 of
its coco.json image record and annotations as canonical JSON (labels_digest: sorted keys, no
spaces; so labels swapped between frames, edited or doubled are refused naming the frame, while
a re-indented coco.json is still the same labels). For the whole set: categories_sha256 (coco's
category table) and manifest_sha256, the digest of the manifest's own content (the project the
views use included), so an edited or damaged manifest is refused too. These guard against
accidents (copies, swaps, truncation, bit rot, hand edits), not against someone who rewrites
the digests with the files.

Checked when a set is opened (read_index, index_problems; no frame file is read): spec, manifest
and coco.json as untrusted files (datasets.files); every listed frame a regular file; each
frame's shape on the project's sensor grid; coco images of that size; every annotation on an
image of the set, of a listed category, inside its image, and not given twice (same image,
category and box); each frame's labels digest. When a frame is read (read_verified_frame): its
bytes' sha256 first (a frame copied over another, swapped or edited), then its header's index,
fingerprint and scale and its irradiance shape against the manifest, and its content
(datasets.dataset.read_frame: finite irradiance ≥ 0 on the labels' pixel grid).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from workbench.datasets.files import (FrameEntry, coco_tables, file_sha256, inside, json_digest,  # noqa: F401
                                      labels_digest, manifest_digest, manifest_frames, read_json_object)
from workbench.errors import InputFileError, ParameterError

RENDER_HINT = "render one with `workbench dataset PROJECT --frames N --out FOLDER`"
VERIFY_COMMAND = "workbench dataset-verify"


@dataclass
class DatasetIndex:
    """A data-set folder's spec, manifest and coco.json, read and checked as files (read_index)."""

    folder: Path
    manifest_path: Path
    manifest: dict
    project: object
    entries: list[FrameEntry]
    coco_path: Path
    coco: dict
    categories: dict[int, str]
    images: dict[int, dict]
    annotations: dict[int, list[dict]]
    rerender_hint: str

    @property
    def fingerprint(self) -> str:
        return self.manifest["fingerprint"]


def rerender_hint(folder: Path, frames: int, project_name: object) -> str:
    """The command whose resume pass re-renders what is damaged and rewrites the index."""
    name = f" ('{project_name}')" if isinstance(project_name, str) and project_name.isprintable() else ""
    return (f"run `workbench dataset PROJECT --frames {frames} --out {folder}` with the project it was "
            f"rendered from{name[:80]}")


def read_index(folder: str | os.PathLike) -> DatasetIndex:
    """The index files of a finished data-set folder; InputFileError naming the first file that is
    missing, malformed, of another data set, or written before frames carried hashes."""
    from workbench.datasets.dataset import DATASET_FORMAT
    from workbench.project import project_from_dict

    folder = Path(folder)
    if not folder.is_dir():
        raise InputFileError(folder, f"no such data-set folder; {RENDER_HINT}")
    spec_path = folder / "dataset_spec.json"
    spec = read_json_object(spec_path, "data-set spec", f"not a workbench data set folder; {RENDER_HINT}")
    if spec.get("format") != DATASET_FORMAT:
        raise InputFileError(spec_path, f"format is not '{DATASET_FORMAT}': a file of another schema")
    manifest_path = folder / "manifest.json"
    manifest = read_json_object(manifest_path, "data-set manifest", "the data set is half-written (its "
                                "frames were not all rendered); rerun the same `workbench dataset` command to finish it")
    if manifest.get("format") != DATASET_FORMAT or manifest.get("fingerprint") != spec.get("fingerprint") \
            or not isinstance(spec.get("fingerprint"), str):
        raise InputFileError(manifest_path, "does not belong to dataset_spec.json (format or fingerprint "
                                            "differ): a file of another schema or another data set")
    try:
        project = project_from_dict(manifest.get("project"), str(manifest_path))
    except (InputFileError, ParameterError) as exc:
        raise InputFileError(manifest_path, f"its project cannot be used: {exc}") from None
    frames = manifest.get("frames")
    hint = rerender_hint(folder, len(frames) if isinstance(frames, list) else 0, project.name)
    if "manifest_sha256" not in manifest:
        raise InputFileError(manifest_path, "was written before data sets recorded a sha256 per frame, so its "
                                            f"frames cannot be checked; {hint} once: it re-renders nothing, "
                                            "checks every frame and writes the hashes")
    entries = manifest_frames(manifest, folder, manifest_path)
    coco_path = inside(folder, manifest.get("coco", "coco.json"), manifest_path, "coco")
    coco = read_json_object(coco_path, "COCO label file", "the data set is half-written; rerun "
                            "`workbench dataset` to finish it")
    categories, images, annotations = coco_tables(coco, coco_path)
    return DatasetIndex(folder, manifest_path, manifest, project, entries, coco_path, coco,
                        categories, images, annotations, hint)


def _frame_file_problem(path: Path) -> str | None:
    if path.is_symlink() or (path.exists() and not path.is_file()):
        return "has a frame's name but is not a regular file (a link, FIFO or device); remove it"
    if not path.exists():
        return "listed in manifest.json but missing: the data set is damaged"
    return None


def annotation_problems(index: DatasetIndex) -> list[InputFileError]:
    """coco.json's annotations against its images and categories: each on an image of the set, of
    a listed category, with its box inside the image, none twice (same image, category, box)."""
    images = {int(im["id"]): im for im in index.images.values()}
    out, seen = [], {}
    for k, a in enumerate(index.coco["annotations"]):
        where = f"annotations[{k}]"
        image = images.get(a["image_id"])
        if image is None:
            out.append(f"{where}.image_id {a['image_id']} is no image of the data set")
            continue
        if a["category_id"] not in index.categories:
            out.append(f"{where}.category_id {a['category_id']} is not one of the categories listed in "
                       f"coco.json ({', '.join(map(str, sorted(index.categories)))})")
        x, y, w, h = a["bbox"]
        if x < 0 or y < 0 or x + w > image["width"] or y + h > image["height"]:
            out.append(f"{where}.bbox {a['bbox']} reaches outside its {image['width']}×{image['height']} "
                       f"image (frame {image['frame_index']})")
        key = (a["image_id"], a["category_id"], tuple(a["bbox"]))
        if key in seen:
            out.append(f"{where} repeats annotations[{seen[key]}] (frame {image['frame_index']}, category "
                       f"{a['category_id']}, box {a['bbox']}): each object is annotated once")
        seen.setdefault(key, k)
    return [InputFileError(index.coco_path, p) for p in out]


def index_problems(index: DatasetIndex) -> list[InputFileError]:
    """Every problem of an opened index that needs no frame file read (module docstring)."""
    rows, cols = index.project.sensor.rows, index.project.sensor.cols
    out = []
    for k, entry in enumerate(index.entries):
        if entry.irradiance_shape[:2] != (rows, cols):
            out.append(InputFileError(index.manifest_path, f"frames[{k}].irradiance_shape {list(entry.irradiance_shape)} "
                                                          f"is not on the data set's {rows}×{cols} sensor grid"))
        problem = _frame_file_problem(entry.path)
        if problem:
            out.append(InputFileError(entry.path, f"{problem}; {index.rerender_hint} to render it again"))
    listed = {e.index for e in index.entries}
    for frame, image in sorted(index.images.items()):
        if frame not in listed:
            out.append(InputFileError(index.coco_path, f"has an image for frame {frame}, which manifest.json does "
                                                       "not list: a file of another data set"))
        elif (image["width"], image["height"]) != (cols, rows):
            out.append(InputFileError(index.coco_path, f"image {image['id']} (frame {frame}) is "
                                                       f"{image['width']}×{image['height']} px, not the frames' "
                                                       f"{cols}×{rows}"))
    out += annotation_problems(index)
    if json_digest(index.coco["categories"]) != index.manifest.get("categories_sha256"):
        out.append(InputFileError(index.coco_path, "its categories are not those the data set was written with "
                                                   "(categories_sha256 in manifest.json): edited or of another data "
                                                   f"set; {index.rerender_hint} to write coco.json again"))
    for entry in index.entries:
        image = index.images.get(entry.index)
        if image is None:
            out.append(InputFileError(index.coco_path, f"has no image for frame {entry.index}; a file of another "
                                                       "data set"))
        elif labels_digest(image, index.annotations.get(image["id"], [])) != entry.labels_sha256:
            out.append(InputFileError(index.coco_path, f"the labels of frame {entry.index} (image {image['id']}) are "
                                                       "not those the data set was written with (labels_sha256 in "
                                                       "manifest.json): swapped with another frame's, edited or "
                                                       f"doubled; {index.rerender_hint} to write coco.json again"))
    if manifest_digest(index.manifest) != index.manifest["manifest_sha256"]:
        out.append(InputFileError(index.manifest_path, "its content is not what was written (manifest_sha256 does "
                                                       f"not match it): edited or damaged; {index.rerender_hint} to "
                                                       "write it again"))
    return out


def raise_first(problems: list[InputFileError], folder: Path) -> None:
    """Raise the first problem, saying how many more there are and which command lists them."""
    if problems:
        first, more = problems[0], len(problems) - 1
        note = f" (and {more} more problem{'s' if more > 1 else ''}: `{VERIFY_COMMAND} {folder}` lists them)" if more else ""
        raise InputFileError(first.path, first.problem + note)


def _header_index(path: Path):
    """The index a frame file's header claims, or None when it cannot be read."""
    from workbench.datasets.dataset import read_frame
    try:
        return read_frame(path, irradiance=False)[1].get("index")
    except InputFileError:
        return None


def read_verified_frame(entry: FrameEntry, fingerprint: str, hint: str):
    """(FrameData, header) of a listed frame, refused (InputFileError naming the frame and `hint`,
    the command that renders it again) unless its bytes are those the manifest recorded and its
    header and irradiance agree with the manifest (module docstring)."""
    from workbench.datasets.dataset import FRAME_VERSION, read_frame
    digest = file_sha256(entry.path)
    if digest != entry.sha256:
        said = _header_index(entry.path)
        why = (f"its header says frame {said}: a frame copied over another or swapped" if said != entry.index
               and isinstance(said, int) else "edited, damaged or replaced")
        raise InputFileError(entry.path, f"its bytes are not those manifest.json recorded for frame {entry.index} "
                                         f"(sha256 {digest[:12]}… ≠ {entry.sha256[:12]}…; {why}); {hint} to render "
                                         "it again")
    try:
        data, head = read_frame(entry.path)
    except InputFileError as exc:
        raise InputFileError(exc.path, f"{exc.problem}; {hint} to render it again") from None
    found = {"index": head.get("index"), "fingerprint": head.get("fingerprint"), "version": head.get("version"),
             "irradiance_shape": data.irradiance_photons.shape, "irradiance_scale": head.get("irradiance_scale")}
    wanted = {"index": entry.index, "fingerprint": fingerprint, "version": FRAME_VERSION,
              "irradiance_shape": entry.irradiance_shape, "irradiance_scale": entry.irradiance_scale}
    wrong = [k for k in wanted if found[k] != wanted[k]]
    if wrong:
        shown = ", ".join(f"{k} {str(found[k])[:24]} ≠ {str(wanted[k])[:24]}" for k in wrong)
        raise InputFileError(entry.path, f"its header disagrees with manifest.json ({shown}): a frame of another "
                                         f"data set or version; {hint} to render it again")
    return data, head


def odd_frame_names(folder: Path) -> list[InputFileError]:
    """Entries of frames/ with a frame's name that are not regular files (links, FIFOs, devices)."""
    from workbench.datasets.dataset import FRAME_NAME, FRAMES_DIR
    out = []
    with os.scandir(folder / FRAMES_DIR) as it:
        for entry in sorted(it, key=lambda e: e.name):
            if FRAME_NAME.fullmatch(entry.name) and not entry.is_file(follow_symlinks=False):
                out.append(InputFileError(entry.path, "has a frame's name but is not a regular file (a link, FIFO "
                                                      "or device); remove it"))
    return out


def verify_dataset(folder: str | os.PathLike, on_frame=None) -> list[InputFileError]:
    """Every problem of a data-set folder (empty when it is valid): the index's, then each frame's
    (every frame is read; on_frame(k, n) is called after each)."""
    try:
        index = read_index(folder)
    except InputFileError as exc:
        return [exc]
    problems = index_problems(index)
    listed = {e.path for e in index.entries}
    problems += [p for p in odd_frame_names(index.folder) if Path(p.path) not in listed]
    bad_files = {p.path for p in problems}
    for k, entry in enumerate(index.entries):
        if str(entry.path) not in bad_files:
            try:
                read_verified_frame(entry, index.fingerprint, index.rerender_hint)
            except InputFileError as exc:
                problems.append(exc)
        if on_frame is not None:
            on_frame(k + 1, len(index.entries))
    return problems

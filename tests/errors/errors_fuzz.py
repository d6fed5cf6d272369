"""Hypothesis strategies and checks for fuzzing project documents, lens files and data-set folders.

A project document is a sample project mutated 1–3 times (a value replaced by a wrong type, NaN,
±inf, an extreme or odd unicode, or scaled; a field deleted; an unknown field added; rarely the
text truncated). `check_document` loads it and, if it loads, simulates it at 16×12 pixels (≤ 64 spp) and
checks that every output is finite and that save → load gives the same project; it returns the
outcome and fails on anything else (another exception, a refusal that names no field, NaN).

A data-set folder is a synthetic 4-frame set with 1–2 mutations of its manifest.json, coco.json,
dataset_spec.json or frame files (`dataset_mutations`); `check_dataset` reads it as a detection
run does (every frame verified and turned into signal rates) and runs dataset-verify on it: it
must be refused naming a file of the set, or read with exactly the unmutated set's content."""
from __future__ import annotations

import json
import math
import contextlib
import io
import os
from pathlib import Path

import numpy as np
from hypothesis import strategies as st

from workbench.errors import InputFileError, ParameterError, WorkbenchError
from workbench.optics.lens.io import LENS_DIR, lens_to_dat
from workbench.project import PROJECTS_DIR, load_project, save_project

SAMPLES = {p.stem: json.loads(p.read_text()) for p in sorted(PROJECTS_DIR.glob("*.json"))}
CHART_SAMPLES = tuple(k for k, v in SAMPLES.items() if v["scene"]["kind"] != "city")
SMALL_ROWS, SMALL_COLS = 12, 16
MAX_FUZZ_SPP = 64

ODD_STRINGS = ["", " ", "\u0000", "\ud800", "\u202e" + "evil", "😀" * 3, "é" * 200, "x" * 5000, "\n\r\t", "NaN", "inf",
               "0.01", "120", "true", "../../etc/passwd", "/etc/passwd", "C:\\x", "null"]
SPECIAL_VALUES = [math.nan, math.inf, -math.inf, 0, 0.0, -0.0, -1, 1, 5e-324, 1e-300, -1e308, 1e308,
                  2 ** 31, 2 ** 63, 2 ** 64, -2 ** 63, 10 ** 30, True, False, None, [], {}, [1, 2], [[1]],
                  {"a": 1}, [math.nan], [0.0, math.inf]]
NASTY = st.one_of(st.sampled_from(SPECIAL_VALUES), st.sampled_from(ODD_STRINGS),
                  st.text(max_size=12), st.integers(min_value=-2 ** 70, max_value=2 ** 70),
                  st.floats(allow_nan=True, allow_infinity=True),
                  st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=4))


def _paths(node, prefix=()) -> list[tuple]:
    """Every location in a decoded JSON document (containers and leaves), the root excluded."""
    out = []
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, value in items:
        out.append(prefix + (key,))
        out.extend(_paths(value, prefix + (key,)))
    return out


def _parent(doc, path):
    for key in path[:-1]:
        doc = doc[key]
    return doc


def mutate_json(draw, doc, paths=None) -> str:
    """Mutate a decoded JSON document in place once (a value replaced by a wrong type, NaN, an
    extreme or odd unicode, or scaled; a field deleted; an unknown field added) at one of `paths`
    (default every location); returns what was done."""
    path = draw(st.sampled_from(paths or _paths(doc)))
    parent, key = _parent(doc, path), path[-1]
    op = draw(st.sampled_from(["nasty", "nasty", "scale", "scale", "scale", "delete", "add"]))
    if op == "scale" and isinstance(parent[key], (int, float)) and not isinstance(parent[key], bool):
        factor = draw(st.sampled_from([-1, 0, 0.5, 2, 10, 1e3, 1e-3]))
        value = parent[key] * factor
        parent[key] = int(value) if isinstance(parent[key], int) else value
    elif op == "delete" and isinstance(parent, dict):
        del parent[key]
    elif op == "add":
        target = parent if isinstance(parent, dict) else doc
        target[draw(st.sampled_from(ODD_STRINGS[1:] + ["extra", "rows", "seed"]))] = draw(NASTY)
    else:
        parent[key] = draw(NASTY)
    return f"{op}:{'.'.join(map(str, path))}"


@st.composite
def project_texts(draw, samples=tuple(SAMPLES)) -> tuple[str, str, list[str]]:
    """(sample name, document text, the mutations applied)."""
    name = draw(st.sampled_from(sorted(samples)))
    doc = json.loads(json.dumps(SAMPLES[name]))
    applied = [mutate_json(draw, doc) for _ in range(draw(st.integers(1, 3)))]
    text = json.dumps(doc, indent=1)
    if draw(st.integers(0, 19)) == 0:
        text = text[: draw(st.integers(0, len(text) - 1))]
        applied.append("truncate")
    return name, text, applied


def _finite(name: str, array) -> None:
    arr = np.asarray(array)
    if arr.dtype.kind in "fc":
        assert np.all(np.isfinite(arr)), f"{name} holds NaN/Inf"


def _cheap_render(render):
    """The render settings with at most MAX_FUZZ_SPP samples per pixel: a scaled-up spp (64 → 64,000)
    is a valid document, checked at load; rendering it in 4,000 chunks would only cost time."""
    cheap = {"max_spp": min(render.max_spp, MAX_FUZZ_SPP)}
    if render.spp is not None:
        cheap["spp"] = min(render.spp, MAX_FUZZ_SPP)
    return render.updated(**cheap)


def check_document(text: str, folder: Path) -> str:
    """Load `text` as a project file; refused → 'refused_field'/'refused_file'; loaded → simulate at
    16×12 and ≤ MAX_FUZZ_SPP spp, check finite outputs and the save round trip → 'simulated' (or 'refused_at_run' for a
    WorkbenchError from a stage). Anything else fails the calling test."""
    from workbench.pipeline import Pipeline
    path = folder / "fuzz.json"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        project = load_project(path)
    except ParameterError as exc:
        assert exc.field and exc.field != "(document)", f"refusal names no field: {exc}"
        assert "\n" not in str(exc)
        return "refused_field"
    except InputFileError as exc:
        assert "\n" not in str(exc)
        return "refused_file"
    saved = save_project(project, folder / "saved.json")
    assert load_project(saved).model_dump() == project.model_dump(), "save → load changed the project"
    small = project.updated(sensor=project.sensor.updated(rows=SMALL_ROWS, cols=SMALL_COLS),
                            render=_cheap_render(project.render))
    try:
        result = Pipeline(small).run()
    except WorkbenchError as exc:
        assert "\n" not in str(exc)
        return "refused_at_run"
    img, isp = result.sensor_image, result.isp
    assert img.dn.shape[:2] == (SMALL_ROWS, SMALL_COLS) and isp.srgb.shape == (SMALL_ROWS, SMALL_COLS, 3)
    for name, array in (("irradiance", result.optical_image.irradiance_photons),
                        ("signal_rate", result.signal_rate_e_per_s), ("electrons", img.electrons),
                        ("volts", img.volts), ("dn", img.dn), ("raw", isp.raw), ("linear", isp.linear),
                        ("srgb", isp.srgb), ("exposure_s", img.exposure_s)):
        _finite(name, array)
    return "simulated"


# ---------------------------------------------------------------- lens files
LENS_TOKENS = ["nan", "inf", "-inf", "0", "-5", "1e308", "-1e308", "100000000", "UNOBTAINIUM", "", "\x00",
               "PARM", "SURF", "STOP", "[", "{", '"', "1e-320"]
ZMX = """VERS 190513 80 123457 L123457
UNIT MM X W X CM MR CPMM
SURF 0
  TYPE STANDARD
  DISZ INFINITY
SURF 1
  TYPE STANDARD
  CURV 0.02
  DISZ 5
  GLAS N-BK7 1 0 1.5168 64.17 0 0 0 0 0 0
  DIAM 10
SURF 2
  STOP
  TYPE STANDARD
  DISZ 2
  DIAM 8
SURF 3
  TYPE EVENASPH
  CURV -0.01
  PARM 2 1e-5
  DISZ 80
  DIAM 10
SURF 4
  TYPE STANDARD
"""


def _lens_bases() -> list[tuple[str, str]]:
    from workbench.optics.lens.io import load_lens
    bases = [(".zmx", ZMX)]
    for p in sorted(LENS_DIR.glob("*.json")):
        bases.append((".json", p.read_text()))
        bases.append((".dat", lens_to_dat(load_lens(p))))
    return bases


LENS_BASES = _lens_bases()


@st.composite
def lens_files(draw) -> tuple[str, bytes, list[str]]:
    """(suffix, file bytes, mutations): a shipped lens (or a Zemax sample) with 1–3 mutations."""
    suffix, text = draw(st.sampled_from(LENS_BASES))
    applied = []
    if suffix == ".json" and draw(st.booleans()):
        doc = json.loads(text)
        surf = draw(st.sampled_from(doc["surfaces"]))
        field = draw(st.sampled_from(["radius", "thickness", "semi_aperture", "glass", "ior"]))
        surf[field] = draw(st.one_of(NASTY, st.sampled_from([0, 0.0, -3.0, "UNOBTAINIUM", "1.2/-5"])))
        applied.append(f"surface.{field}")
        text = json.dumps(doc)
    for _ in range(draw(st.integers(0 if applied else 1, 3))):
        op = draw(st.sampled_from(["token", "token", "truncate", "binary", "duplicate_line"]))
        tokens = text.split(" ")
        if op == "token" and tokens:
            i = draw(st.integers(0, len(tokens) - 1))
            tokens[i] = draw(st.sampled_from(LENS_TOKENS))
            text = " ".join(tokens)
        elif op == "truncate" and text:
            text = text[: draw(st.integers(0, len(text) - 1))]
        elif op == "duplicate_line":
            lines = text.splitlines()
            if lines:
                i = draw(st.integers(0, len(lines) - 1))
                text = "\n".join(lines[: i + 1] + lines[i:])
        applied.append(op)
    data = text.encode("utf-8", errors="surrogatepass")
    if "binary" in applied:
        i = draw(st.integers(0, len(data)))
        data = data[:i] + draw(st.binary(min_size=1, max_size=16)) + data[i:]
    return suffix, data, applied


def check_lens_file(suffix: str, data: bytes, folder: Path) -> str:
    """Load a lens file: 'refused' (InputFileError naming it, one line), else 'loaded' and then
    `workbench lens info` on it must succeed or print one error line (no traceback)."""
    from workbench.cli import main
    from workbench.optics.lens.io import load_lens
    path = folder / f"fuzz{suffix}"
    path.write_bytes(data)
    try:
        load_lens(path)
    except InputFileError as exc:
        assert str(exc).startswith(str(path)) and "\n" not in str(exc)
        return "refused"
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(["lens", "info", str(path)])
    lines = err.getvalue().strip().splitlines()
    assert code == 0 or (code == 2 and len(lines) == 1 and lines[0].startswith("workbench lens info: error:")), \
        err.getvalue()
    return "loaded" if code == 0 else "loaded_info_refused"


# ---------------------------------------------------------------- data-set folders
DATASET_FRAMES = 4
_BASE: dict = {}


def base_dataset() -> tuple[Path, dict]:
    """(folder, content) of a synthetic 4-frame data set made once per process (dataset_content)."""
    if not _BASE:
        import atexit
        import shutil
        import tempfile

        from workbench.detect.synthetic import make_synthetic_dataset
        folder = Path(tempfile.mkdtemp(prefix="fuzz-dataset-")) / "set"
        atexit.register(shutil.rmtree, folder.parent, True)
        make_synthetic_dataset(folder, frames=DATASET_FRAMES)
        _BASE.update(folder=folder, content=dataset_content(folder))
    return _BASE["folder"], _BASE["content"]


def dataset_content(folder: Path) -> dict:
    """Everything a detection run takes from a data-set folder: the project, the frame records
    (seeds, split, boxes) and each frame's data and signal rates, every frame read and verified
    as a view reads it. InputFileError (or another exception) when the folder is refused."""
    import hashlib

    from workbench.datasets.integrity import read_verified_frame
    from workbench.detect.data import DetectionDataset, experiment_sensor, load_signal_rates
    ds = DetectionDataset(folder)
    sensor = experiment_sensor(ds.project)
    frames = []
    for rec in ds.frames:
        data, _ = read_verified_frame(rec.entry, ds.fingerprint, rec.rerender_hint)
        arrays = {"irradiance": data.irradiance_photons, "wavelengths": data.wavelengths_nm,
                  **data.labels.to_arrays(), **dict(enumerate(load_signal_rates(rec, sensor, ds.fingerprint)))}
        frames.append({"index": rec.index, "file": rec.path.name, "seeds": rec.seeds, "split": rec.split,
                       "boxes": [a.tolist() for a in (rec.boxes_xyxy, rec.classes, rec.truncation, rec.ignored_xyxy,
                                                      rec.ignored_classes)],
                       "meta": json.dumps([data.meta, data.labels.meta], sort_keys=True, default=str),
                       "arrays": {str(k): hashlib.sha256(np.ascontiguousarray(v).tobytes()).hexdigest()
                                  + str(v.dtype) + str(v.shape) for k, v in arrays.items()}})
    return {"project": ds.project.model_dump_json(), "fingerprint": ds.fingerprint, "classes": ds.class_names,
            "image_hw": ds.image_hw, "frames": frames}


def _rewrite_frame(path: Path, change) -> None:
    """Rewrite a frame file with change(arrays, header) applied (a valid .npz, other bytes)."""
    import zipfile

    from frame_edits import rewrite_frame
    try:
        rewrite_frame(path, change, data=_read(path))
    except (ValueError, KeyError, IndexError, TypeError, EOFError, OSError, zipfile.BadZipFile) as exc:
        raise _CannotApply(path) from exc


def _reseal(folder: Path, indices) -> None:
    """Record the present bytes of frames `indices` in manifest.json, and its own digest, as a
    writer would: what refuses the frame is then the check behind the hash."""
    import hashlib

    from workbench.datasets.integrity import manifest_digest
    path = folder / "manifest.json"
    doc = _load_json(path)
    for i in indices:
        doc["frames"][i]["sha256"] = hashlib.sha256(_read(_frame(folder, i))).hexdigest()
    doc["manifest_sha256"] = manifest_digest(doc)
    path.write_text(json.dumps(doc, indent=1))


def _frame(folder: Path, i: int) -> Path:
    return folder / "frames" / f"frame_{i:06d}.npz"


class _CannotApply(Exception):
    """A mutation that cannot be applied to what an earlier one left (a frame made a FIFO, a file
    no longer JSON or no longer an .npz)."""


def _read(path: Path) -> bytes:
    """A mutated file's bytes; _CannotApply unless it is still a regular file (never a FIFO or device)."""
    if path.is_symlink() or not path.is_file():
        raise _CannotApply(path)
    return path.read_bytes()


def _load_json(path: Path):
    try:
        return json.loads(_read(path))
    except ValueError:
        raise _CannotApply(path) from None


# Frame edits whose content a writer could never have recorded: refused behind a matching hash too.
HEADER_EDITS = {
    "index+1": lambda a, h: h.update(index=h["index"] + 1),
    "fingerprint": lambda a, h: h.update(fingerprint="0" * 40),
    "version": lambda a, h: h.update(version=h["version"] + 1),
    "format": lambda a, h: h.update(format="another-format"),
    "scale x2": lambda a, h: h.update(irradiance_scale=h["irradiance_scale"] * 2),
    "scale abc": lambda a, h: h.update(irradiance_scale="abc"),
    "scale -1": lambda a, h: h.update(irradiance_scale=-1.0),
    "scale 0": lambda a, h: h.update(irradiance_scale=0),
    "scale NaN": lambda a, h: h.update(irradiance_scale=math.nan),
    "scale 1e300": lambda a, h: h.update(irradiance_scale=1e300),
    "scale list": lambda a, h: h.update(irradiance_scale=[1.0]),
    "scale missing": lambda a, h: h.pop("irradiance_scale"),
    "header a list": lambda a, h: (h.clear(), a.update(header_json=np.asarray("[1, 2]"))),
}
ARRAY_EDITS = {
    "irradiance half size": lambda a: a.update(irradiance=a["irradiance"][::2, ::2]),
    "irradiance transposed": lambda a: a.update(irradiance=np.ascontiguousarray(a["irradiance"].transpose(1, 0, 2))),
    "irradiance 2 bands": lambda a: a.update(irradiance=a["irradiance"][:, :, :2]),
    "irradiance 2-D": lambda a: a.update(irradiance=a["irradiance"][:, :, 0]),
    "labels half size": lambda a: a.update(depth_m=a["depth_m"][::2, ::2], class_id=a["class_id"][::2, ::2],
                                           instance_id=a["instance_id"][::2, ::2],
                                           planar_depth_m=a["planar_depth_m"][::2, ::2]),
    "one label map off": lambda a: a.update(depth_m=a["depth_m"][:-1]),
    "wavelengths short": lambda a: a.update(wavelengths_nm=a["wavelengths_nm"][:-1]),
    "negative irradiance": lambda a: a.update(irradiance=-a["irradiance"]),
    "a NaN": lambda a: a["irradiance"].__setitem__((0, 0, 0), np.nan),
    "an Inf": lambda a: a["irradiance"].__setitem__((1, 1, 0), np.inf),
    "integer irradiance": lambda a: a.update(irradiance=a["irradiance"].astype(np.int32)),
    "float64 irradiance": lambda a: a.update(irradiance=a["irradiance"].astype(np.float64)),
    "complex irradiance": lambda a: a.update(irradiance=a["irradiance"].astype(np.complex64)),
    "no irradiance": lambda a: a.pop("irradiance"),
    "no labels": lambda a: a.pop("instance_id"),
    "object table short": lambda a: a.update(obj_bbox_xywh=a["obj_bbox_xywh"][:-1]),
    "object ids as text": lambda a: a.update(obj_instance_id=np.asarray(["x"] * len(a["obj_instance_id"]))),
}


def _frame_mutation(draw, folder_ops: list, applied: list) -> None:
    """One frame-file mutation (bytes, copies, swaps, header, arrays, odd files); some resealed."""
    i = draw(st.integers(0, DATASET_FRAMES - 1))
    j = draw(st.integers(0, DATASET_FRAMES - 1).filter(lambda k: k != i))
    op = draw(st.sampled_from(["flip", "flip", "truncate", "append", "copy", "swap", "header", "header",
                               "arrays", "arrays", "odd", "same"]))
    reseal = draw(st.booleans()) and op not in ("odd", "same")
    if op == "flip":
        where, mask = draw(st.floats(0, 1, exclude_max=True)), draw(st.integers(1, 255))

        def apply(folder):
            data = bytearray(_read(_frame(folder, i)))
            if not data:
                raise _CannotApply("an empty file has no byte to flip")
            data[int(where * len(data))] ^= mask
            _frame(folder, i).write_bytes(bytes(data))
        what = f"flip byte at {where:.3f} of frame {i}"
    elif op == "truncate":
        keep = draw(st.floats(0, 1, exclude_max=True))

        def apply(folder):
            data = _read(_frame(folder, i))
            _frame(folder, i).write_bytes(data[:int(keep * len(data))])
        what = f"truncate frame {i} to {keep:.3f}"
    elif op == "append":
        junk = draw(st.binary(min_size=1, max_size=64))

        def apply(folder):
            _frame(folder, i).write_bytes(_read(_frame(folder, i)) + junk)
        what = f"append {len(junk)} bytes to frame {i}"
    elif op == "copy":
        def apply(folder):
            _frame(folder, i).write_bytes(_read(_frame(folder, j)))
        what = f"frame {j} copied over frame {i}"
    elif op == "swap":
        def apply(folder):
            a, b = _read(_frame(folder, i)), _read(_frame(folder, j))
            _frame(folder, i).write_bytes(b)
            _frame(folder, j).write_bytes(a)
        what = f"frames {i} and {j} swapped"
    elif op == "header":
        name = draw(st.sampled_from(sorted(HEADER_EDITS)))

        def apply(folder):
            _rewrite_frame(_frame(folder, i), HEADER_EDITS[name])
        what = f"header of frame {i}: {name}"
    elif op == "arrays":
        name = draw(st.sampled_from(sorted(ARRAY_EDITS)))

        def apply(folder):
            _rewrite_frame(_frame(folder, i), lambda a, h: ARRAY_EDITS[name](a))
        what = f"arrays of frame {i}: {name}"
    elif op == "odd":
        kind = draw(st.sampled_from(["fifo", "dev-zero", "link to another frame", "folder", "missing", "empty"]))

        def apply(folder):
            path = _frame(folder, i)
            if path.is_dir() and not path.is_symlink():
                raise _CannotApply(path)
            path.unlink()
            if kind == "fifo":
                os.mkfifo(path)
            elif kind == "dev-zero":
                path.symlink_to("/dev/zero")
            elif kind == "link to another frame":
                path.symlink_to(_frame(folder, j))
            elif kind == "folder":
                path.mkdir()
            elif kind == "empty":
                path.write_bytes(b"")
        what = f"frame {i} replaced by: {kind}"
    else:
        def apply(folder):
            _frame(folder, i).write_bytes(_read(_frame(folder, i)))
        what = f"frame {i} rewritten with its own bytes"
    folder_ops.append(apply)
    if reseal:
        folder_ops.append(lambda folder: _reseal(folder, {i, j} if op == "swap" else {i}))
        what += " (resealed)"
    applied.append(what)


def _coco_specials(draw) -> tuple[str, object]:
    """A targeted coco.json edit: (what, change(doc))."""
    k = draw(st.integers(0, 1000))

    def ann(d):
        return d["annotations"][k % len(d["annotations"])]

    def swap_images(d):
        for a in d["annotations"]:
            a["image_id"] = {1: 2, 2: 1}.get(a["image_id"], a["image_id"])
    edits = {
        "an annotation doubled": lambda d: d["annotations"].append(dict(ann(d))),
        "every annotation doubled": lambda d: d.update(annotations=d["annotations"] * 2),
        "unknown category": lambda d: ann(d).update(category_id=99),
        "another valid category": lambda d: ann(d).update(category_id=1 + ann(d)["category_id"] % 3),
        "labels of frames 0 and 1 swapped": swap_images,
        "frame indices of two images swapped": lambda d: (d["images"][0].update(frame_index=1),
                                                          d["images"][1].update(frame_index=0)),
        "box shifted outside": lambda d: ann(d).update(bbox=[ann(d)["bbox"][0] + 1000] + ann(d)["bbox"][1:]),
        "box moved by a pixel": lambda d: ann(d).update(bbox=[ann(d)["bbox"][0] + 1] + ann(d)["bbox"][1:]),
        "image size doubled": lambda d: d["images"][0].update(width=128, height=96),
        "an annotation dropped": lambda d: d["annotations"].pop(k % len(d["annotations"])),
        "categories renamed": lambda d: [c.update(name=c["name"][::-1]) for c in d["categories"]],
        "an image dropped": lambda d: d["images"].pop(k % len(d["images"])),
        "images listed in reverse (same labels)": lambda d: d["images"].reverse(),
        "info edited (not read)": lambda d: d.update(info={"description": "edited"}),
    }
    name = draw(st.sampled_from(sorted(edits)))
    return name, edits[name]


@st.composite
def dataset_mutations(draw) -> tuple[str, object, list[str]]:
    """(file kind, apply(folder), the mutations applied): 1–2 mutations of one kind of file of a
    synthetic data set: manifest.json, coco.json, dataset_spec.json (JSON edits, targeted edits,
    truncation, byte flips, re-indenting) or frame files (_frame_mutation)."""
    kind = draw(st.sampled_from(("frame", "coco.json", "manifest.json", "frame", "coco.json", "manifest.json", "frame",
                                 "dataset_spec.json")))
    ops, applied = [], []
    doc = None if kind == "frame" else json.loads((base_dataset()[0] / kind).read_text())
    for _ in range(draw(st.integers(1, 2))):
        if kind == "frame":
            _frame_mutation(draw, ops, applied)
            continue
        style = draw(st.sampled_from(["json", "json", "json", "special", "truncate", "flip", "reindent"]))
        if style == "special" and kind == "coco.json":
            name, change = _coco_specials(draw)
            applied.append(name)
            ops.append(lambda folder, change=change: _edit_json(folder / kind, change))
        elif style == "special" and kind == "manifest.json":
            i = draw(st.integers(0, DATASET_FRAMES - 1))
            field = draw(st.sampled_from(["sha256", "labels_sha256", "irradiance_shape", "irradiance_scale", "seeds",
                                          "index", "entry"]))

            def change(d, i=i, field=field):
                other = d["frames"][(i + 1) % len(d["frames"])]
                if field == "entry":
                    d["frames"][i], d["frames"][(i + 1) % len(d["frames"])] = other, d["frames"][i]
                else:
                    d["frames"][i][field] = other[field]
            applied.append(f"frames[{i}].{field} taken from the next frame")
            ops.append(lambda folder, change=change: _edit_json(folder / kind, change))
        elif style in ("truncate", "flip"):
            where = draw(st.floats(0, 1, exclude_max=True))
            mask = draw(st.integers(1, 255))

            def apply(folder, where=where, mask=mask, style=style):
                data = bytearray(_read(folder / kind))
                if not data:
                    raise _CannotApply("an empty file has no byte to flip or cut")
                if style == "truncate":
                    del data[int(where * len(data)):]
                else:
                    data[int(where * len(data))] ^= mask
                (folder / kind).write_bytes(bytes(data))
            applied.append(f"{style} at {where:.3f}")
            ops.append(apply)
        elif style == "reindent":
            applied.append("re-indented, keys sorted (same content)")
            ops.append(lambda folder: (folder / kind).write_text(
                json.dumps(_load_json(folder / kind), indent=3, sort_keys=True)))
        else:
            applied.append(mutate_json(draw, doc))
            text = json.dumps(doc)
            ops.append(lambda folder, text=text: (folder / kind).write_text(text, errors="surrogatepass"))

    def apply_all(folder):
        for op in ops:
            try:
                op(folder)
            except _CannotApply:       # a later edit of a file an earlier one broke: the earlier stands
                pass
    return kind, apply_all, applied


def _edit_json(path: Path, change) -> None:
    doc = _load_json(path)
    try:
        change(doc)
    except (KeyError, IndexError, TypeError, AttributeError, ZeroDivisionError) as exc:
        raise _CannotApply(path) from exc
    path.write_text(json.dumps(doc))


def check_dataset(case, folder: Path) -> str:
    """Copy the base data set into `folder`, mutate it, read it as a detection run would and
    verify it: 'refused' (an InputFileError naming a file of the set, one line; dataset-verify
    reports ≥ 1 problem) or 'accepted_same' (the same content as the unmutated set; dataset-verify
    reports none). 'accepted_wrong' and 'verify_disagrees' are failures; any other exception
    reaches the caller (an internal error)."""
    import shutil

    from workbench.datasets.integrity import verify_dataset
    base, content = base_dataset()
    _kind, apply, _applied = case
    target = folder / "set"
    shutil.copytree(base, target)
    apply(target)
    try:
        got = dataset_content(target)
    except InputFileError as exc:
        assert "\n" not in str(exc) and exc.path.startswith(str(target)), f"refusal names no file of the set: {exc}"
        outcome = "refused"
    else:
        outcome = "accepted_same" if got == content else "accepted_wrong"
    problems = verify_dataset(target)
    assert all(p.path.startswith(str(target)) and "\n" not in str(p) for p in problems), problems[:3]
    if bool(problems) != (outcome == "refused"):
        return "verify_disagrees"
    return outcome
# ---------------------------------------------------------------- read-back files (issue 34)
# Files the workbench wrote and reads back — a results.json, a study.json, a training checkpoint —
# mutated 1–3 times (a value replaced by a wrong type or NaN, scaled, deleted, an entry duplicated
# or added; then rarely the bytes flipped or truncated). Each must be refused with an
# InputFileError naming the file (or, for a study, OutputPathError naming a folder of another
# study), or accepted with the same meaning as the file that was written. A file whose 'checksum'
# entry itself was deleted is the format written before sealing (accepted on structural checks):
# its outcome is counted apart ('…_unsealed').

def _mutate_json(draw, doc, applied: list[str]):
    """Apply one mutation to a decoded JSON document in place (or return a replacement root)."""
    paths = _paths(doc)
    if not paths:
        return doc
    path = draw(st.sampled_from(paths))
    parent, key = _parent(doc, path), path[-1]
    op = draw(st.sampled_from(["nasty", "nasty", "scale", "delete", "add", "duplicate", "out_of_range"]))
    value = parent[key]
    if op == "scale" and isinstance(value, (int, float)) and not isinstance(value, bool):
        factor = draw(st.sampled_from([-1, 0, 0.5, 2, 10, 1e3, 1e-3]))
        parent[key] = int(value * factor) if isinstance(value, int) else value * factor
    elif op == "out_of_range" and isinstance(value, (int, float)) and not isinstance(value, bool):
        parent[key] = draw(st.sampled_from([2.5, -0.1, 1.0000001, math.nan, math.inf, -math.inf, 1e308]))
    elif op == "delete":
        del parent[key]
    elif op == "add":
        target = parent if isinstance(parent, dict) else doc
        if isinstance(target, dict):
            target[draw(st.sampled_from(["extra", "seed", "key", "map", "design", "role", "checksum"]))] = draw(NASTY)
    elif op == "duplicate" and isinstance(value, list) and value:
        value.append(json.loads(json.dumps(draw(st.sampled_from(value)))))
    elif op == "duplicate" and isinstance(parent, list):
        parent.append(json.loads(json.dumps(value)))
    else:
        parent[key] = draw(NASTY)
        op = "nasty"
    applied.append(f"{op}:{'.'.join(map(str, path))[:60]}")
    return doc


def _mutate_bytes(draw, data: bytes, applied: list[str]) -> bytes:
    """Rarely (1 in 5) flip, truncate or insert bytes."""
    if not data or draw(st.integers(0, 4)) != 0:
        return data
    op = draw(st.sampled_from(["flip", "flip", "truncate", "insert"]))
    i = draw(st.integers(0, len(data) - 1))
    if op == "flip":
        data = data[:i] + bytes([data[i] ^ draw(st.integers(1, 255))]) + data[i + 1:]
    elif op == "truncate":
        data = data[:i]
    else:
        data = data[:i] + draw(st.binary(min_size=1, max_size=16)) + data[i:]
    applied.append(op)
    return data


@st.composite
def mutated_json_files(draw, base_text: str) -> tuple[str, bytes, list[str]]:
    """('json', file bytes, mutations) of a JSON document mutated 1–3 times."""
    doc = json.loads(base_text)
    applied: list[str] = []
    for _ in range(draw(st.integers(1, 3))):
        doc = _mutate_json(draw, doc, applied)
    data = json.dumps(doc, indent=1).encode("utf-8", errors="surrogatepass")
    return "json", _mutate_bytes(draw, data, applied), applied


def _unsealed(applied: list[str]) -> bool:
    """Whether a mutation deleted a checksum (the file then reads as one written before sealing)."""
    return any(a.startswith("delete:") and a.endswith("checksum") for a in applied)


TINY_FUZZ_PROFILE = dict(name="tiny", image_hw=(48, 64), nets=("mobile",), seeds=2, epochs={"mobile": 1},
                         batch_size=4, crop_hw=None, lr=3e-3, per_ev_biases=(), threads=1, device="cpu",
                         loader_workers=0, cache_mb=64.0, curve_points=1, note="fuzz")


def results_document() -> str:
    """A sealed results.json of a 2-seed ISP experiment (records made up, sealed as the code seals
    them; one superseded run of an earlier 2-epoch budget) as text."""
    from dataclasses import asdict, replace as dc_replace

    from workbench.experiments.detection import RESULTS_FORMAT, RESULTS_SCHEMA_VERSION, Profile, _analysis
    from workbench.experiments.detection import plan_configs
    from workbench.experiments.records import seal_document, seal_record
    profile = Profile(**TINY_FUZZ_PROFILE)
    fingerprint, evs = "0123456789abcdef", (-1.0, 0.0, 1.0)
    rng = np.random.default_rng(3)

    def record(role, key, config, test_evs) -> dict:
        epochs = config.epochs
        return {"key": key, "role": role, "config": json.loads(config.to_json()), "classes": ["car", "pedestrian"],
                "device": "cpu", "machine": {"cpu": "fuzz", "threads": 1, "wall_s": 10.0, "cpu_s": 9.0},
                "train": {"epochs": epochs, "steps": 3 * epochs, "images": 12 * epochs, "seconds": 5.0,
                          "train_ms_per_image": 40.0, "step_ms_per_image": 30.0, "sensor_isp_ms_per_image": 5.0,
                          "final_loss": 2.5, "history": [{"epoch": e, "loss": 3.0 - 0.1 * e} for e in
                                                         range(1, epochs + 1)],
                          "curve": [{"epoch": epochs, "images": 12 * epochs, "train_map": 0.3}],
                          "train_map": 0.31, "train_map_half": None, "train_map_end": None, "half_gain": None,
                          "converged": None, "convergence": "unknown", "autocast": "fp32", "train_map_ev": 0.0},
                "tests": [{"ev": ev, "map": float(rng.uniform(0.2, 0.6)), "coco_ap50": 0.4,
                           "ap": {"car": float(rng.uniform(0.2, 0.7)), "pedestrian": None}, "seconds": 1.0}
                          for ev in test_evs]}
    runs = [seal_record(record(*planned), fingerprint) for planned in plan_configs("isp", profile, 2, evs, fingerprint)]
    old = dc_replace(profile, epochs={"mobile": 2})
    superseded = [seal_record(record(*plan_configs("isp", old, 1, evs, fingerprint)[0]), fingerprint)]
    doc = {"format": RESULTS_FORMAT, "schema_version": RESULTS_SCHEMA_VERSION, "kind": "isp", "profile": "tiny",
           "project": "fuzz", "dataset": {"folder": "set", "fingerprint": fingerprint, "frames": 14, "stats": {}},
           "classes": ["car", "pedestrian"], "ev_biases": list(evs), "settings": {**asdict(profile), "seeds": 2},
           "code_version": "fuzz", "runs": runs, **_analysis("isp", runs, {}, list(evs)), "complete": True,
           "superseded_runs": superseded}
    return json.dumps(seal_document(doc), indent=1)


def check_results_file(data: bytes, folder: Path, original: dict, applied: list[str]) -> str:
    """Read a mutated results.json: 'refused' (InputFileError naming it), else it must mean what
    `original` means ('accepted_same'); a legacy (unsealed) document that reads otherwise counts
    as 'accepted_changed_unsealed'. What it reads is then analysed and tabled (no error)."""
    from workbench.experiments.detection import _analysis, result_rows
    from workbench.experiments.results import read_results
    path = folder / "results.json"
    path.write_bytes(data)
    try:
        doc = read_results(folder)
    except InputFileError as exc:
        assert exc.path == str(path) and "\n" not in str(exc), str(exc)
        return "refused"
    result_rows(doc["runs"])
    if doc.get("runs"):
        _analysis(doc["kind"], doc["runs"], {}, doc["ev_biases"])
    if json.dumps(doc, sort_keys=True) == json.dumps(original, sort_keys=True):
        return "accepted_same"
    return _changed(applied, sealed="checksum" in original)


def _changed(applied: list[str], sealed: bool) -> str:
    """The outcome of a file accepted with another meaning: a failure for a sealed file whose
    checksum was left in place; counted apart for one written (or made to look written) before
    sealing, whose numbers in range cannot be told from the ones written."""
    if not sealed or _unsealed(applied):
        return "accepted_changed_unsealed"
    raise AssertionError(f"accepted wrong: {applied}")


STUDY_VARY = {"optics.f_number": [2, 4, 8]}


def study_project():
    from workbench.project import load_project
    p = load_project("paper_camera")
    return p.updated(name="fuzz_camera", sensor=p.sensor.updated(rows=120, cols=160))


def study_document(sealed: bool = True) -> str:
    """A study.json with two of the three designs of STUDY_VARY measured (numbers made up), with
    the designs' checksums or (sealed=False) as written before them."""
    from workbench.metrics.study import METRICS_VERSION, STUDY_FORMAT, design_grid, seal_design
    project = study_project()
    grid = design_grid(project, STUDY_VARY)
    designs = [seal_design({"design": name, "values": values, "project": project.name,
                            "summary": {"mtf50_cy_px": 0.2 + 0.01 * k, "snr_at_10pct_full_well_dB": 30.0,
                                        "delta_e_mean": 2.0, "dynamic_range_dB": None},
                            "mtf": [{"plane": "sRGB luminance", "mtf50_cy_px": 0.2}], "seconds": 3.0 + k})
               for k, (name, values, _) in enumerate(grid[:2])]
    if not sealed:
        designs = [{k: v for k, v in d.items() if k != "checksum"} for d in designs]
    doc = {"format": STUDY_FORMAT, "project": project.name, "vary": STUDY_VARY, "detector": None,
           "planned": len(grid), "notes": [], "metrics_version": METRICS_VERSION, "designs": designs}
    return json.dumps(doc, indent=1)


def check_study_file(data: bytes, folder: Path, original: dict, applied: list[str]) -> str:
    """Resume a study on a mutated study.json up to its first progress report: 'refused'
    (InputFileError naming the file), 'refused_other_study' (OutputPathError naming the folder:
    the file is of another study), else each design it keeps must be the original's
    ('accepted_same'; 'accepted_resumes' when some are to be measured again)."""
    from workbench.errors import OutputPathError
    from workbench.metrics.study import run_study
    out = folder / "s"
    out.mkdir(exist_ok=True)
    path = out / "study.json"
    path.write_bytes(data)
    job = run_study(study_project(), STUDY_VARY, out)
    try:
        progress = next(job)
    except InputFileError as exc:
        assert exc.path == str(path) and "\n" not in str(exc), str(exc)
        return "refused"
    except OutputPathError as exc:
        assert exc.path == str(out) and "another study" in str(exc), str(exc)
        return "refused_other_study"
    finally:
        job.close()
    assert progress.done <= progress.total == 3, (progress.done, progress.total)
    from workbench.metrics.study import METRICS_VERSION
    doc = json.loads(data)
    if doc.get("metrics_version", 1) != METRICS_VERSION:      # measured by other metrics: all measured again
        assert progress.done == 0, progress
        return "accepted_resumes"
    kept = doc["designs"]
    by_name = {d["design"]: d for d in original["designs"]}
    if all(d == by_name.get(d.get("design")) for d in kept):
        return "accepted_same" if len(kept) == len(by_name) else "accepted_resumes"
    return _changed(applied, sealed=all("checksum" in d for d in original["designs"]))


TINY_TRAIN = dict(net="mobile", representation="srgb", epochs=2, batch_size=4, threads=1, device="cpu",
                  curve_points=2, curve_frames=4)
CHECKPOINT_FIELDS = ("epoch", "step", "images", "done", "elapsed_s", "step_s", "history", "curve", "config",
                     "format", "checksum")


@st.composite
def mutated_checkpoints(draw, state: dict) -> tuple[str, bytes, list[str]]:
    """('pt', file bytes, mutations): a finished training state mutated 1–3 times (its counters,
    history, curve, config or format; a weight set to NaN/Inf or scaled, removed, reshaped or
    added; an entry duplicated or added), saved with its old checksum, then rarely byte-mutated."""
    import copy

    import torch
    state = copy.deepcopy(state)
    applied: list[str] = []
    for _ in range(draw(st.integers(1, 3))):
        target = draw(st.sampled_from(["meta", "meta", "weights"]))
        if target == "weights":
            model = state["model"]
            name = draw(st.sampled_from(sorted(model)))
            op = draw(st.sampled_from(["nan", "inf", "scale", "delete", "reshape", "add"]))
            if op in ("nan", "inf") and model[name].is_floating_point() and model[name].numel():
                flat = model[name].clone().reshape(-1)
                flat[draw(st.integers(0, flat.numel() - 1))] = math.nan if op == "nan" else math.inf
                model[name] = flat.reshape(model[name].shape)
            elif op == "scale" and model[name].is_floating_point():
                model[name] = model[name] * draw(st.sampled_from([0.0, -1.0, 1.001, 1e6]))
            elif op == "delete":
                del model[name]
            elif op == "reshape":
                model[name] = torch.zeros(3, 1)
            else:
                model["extra.weight"] = torch.ones(2)
            applied.append(f"weights:{op}:{name}")
        else:
            meta = {k: state[k] for k in CHECKPOINT_FIELDS if k in state}
            meta = _mutate_json(draw, json.loads(json.dumps(meta)), applied)
            for k in CHECKPOINT_FIELDS:
                state.pop(k, None)
            state.update(meta)
    import io as _io
    buf = _io.BytesIO()
    torch.save(state, buf)
    return "pt", _mutate_bytes(draw, buf.getvalue(), applied), applied


def check_checkpoint_file(data: bytes, folder: Path, dataset, reference, applied: list[str],
                          sealed: bool = True) -> str:
    """Resume training from a mutated checkpoint: 'refused' (InputFileError naming it), else the
    run must be the finished reference run, weights and history alike ('accepted_same'); sealed:
    whether the checkpoint it was made from had a checksum."""
    import torch

    from workbench.detect.engine import TrainConfig, train_detector
    path = folder / "run.pt"
    path.write_bytes(data)
    try:
        model, result = train_detector(dataset, TrainConfig(**TINY_TRAIN), path)
    except InputFileError as exc:
        assert exc.path == str(path) and "\n" not in str(exc), str(exc)
        return "refused"
    weights, history = reference
    same = (result.epochs == TINY_TRAIN["epochs"] and result.history == history
            and all(torch.equal(v, weights[k]) for k, v in model.state_dict().items()))
    if same:
        return "accepted_same"
    return _changed(applied, sealed=sealed)

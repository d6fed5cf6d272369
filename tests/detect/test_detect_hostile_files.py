"""Files inside a data-set or results folder are untrusted input: every hostile variant is refused
with an InputFileError naming the file (never another exception, never a read outside the
folder, never a double-counted frame, never an allocation a header merely declares)."""
from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest
from frame_edits import edit_json

from workbench.detect.data import DetectionDataset
from workbench.errors import InputFileError


def _deep(depth=100_000):
    return "[" * depth + "]" * depth


MANIFEST_CASES = {
    "frames not a list": lambda d: d.update(frames="notalist"),
    "a frame listed twice": lambda d: d["frames"].append(d["frames"][0]),
    "a frame path outside the folder": lambda d: d["frames"][0].update(file="../../../etc/passwd"),
    "a frame path to another frame": lambda d: d["frames"][0].update(file=d["frames"][1]["file"]),
    "seeds as a list": lambda d: d["frames"][0].update(seeds=[1, 2, 3]),
    "an index that is text": lambda d: d["frames"][0].update(index="0"),
    "a negative seed": lambda d: d["frames"][0]["seeds"].update(pose=-1),
    "coco outside the folder": lambda d: d.update(coco="/etc/hostname"),
    "coco up a level": lambda d: d.update(coco="../coco.json"),
    "fingerprint of another set": lambda d: d.update(fingerprint="0" * 40),
    "a sha256 that is not hex": lambda d: d["frames"][0].update(sha256="z" * 64),
    "a sha256 that is a number": lambda d: d["frames"][1].update(sha256=12),
    "no labels digest": lambda d: d["frames"][0].pop("labels_sha256"),
    "an irradiance shape as text": lambda d: d["frames"][0].update(irradiance_shape="48x64x3"),
    "an irradiance shape of two numbers": lambda d: d["frames"][0].update(irradiance_shape=[48, 64]),
    "an irradiance scale 'abc'": lambda d: d["frames"][0].update(irradiance_scale="abc"),
    "an irradiance scale of -1": lambda d: d["frames"][0].update(irradiance_scale=-1),
    "no manifest digest": lambda d: d.pop("manifest_sha256"),
}
COCO_CASES = {
    "bbox text": lambda d: d["annotations"][0].update(bbox="abcd"),
    "bbox with NaN": lambda d: d["annotations"][0].update(bbox=[0, 0, float("nan"), 3]),
    "negative width": lambda d: d["annotations"][0].update(bbox=[0, 0, -5, 3]),
    "image listed twice": lambda d: d["images"].append(d["images"][0]),
    "annotations an object": lambda d: d.update(annotations={}),
    "category without a name": lambda d: d["categories"][0].pop("name"),
    "occlusion 7": lambda d: d["annotations"][0].update(occlusion=7),
    "image width as text": lambda d: d["images"][0].update(width="64"),
    "image height 0": lambda d: d["images"][0].update(height=0),
    "an annotation of no image": lambda d: d["annotations"][0].update(image_id=999),
    "an annotation listed twice": lambda d: d["annotations"].append(d["annotations"][0]),
    "an unknown category": lambda d: d["annotations"][0].update(category_id=42),
    "a box past the right edge": lambda d: d["annotations"][0].update(bbox=[60, 0, 10, 10]),
    "a box left of the frame": lambda d: d["annotations"][0].update(bbox=[-1, 0, 10, 10]),
}


@pytest.mark.parametrize("case", sorted(MANIFEST_CASES))
def test_a_hostile_manifest_is_refused_naming_it(copy, case):
    edit_json(copy, "manifest.json", MANIFEST_CASES[case])
    with pytest.raises(InputFileError, match="manifest.json|dataset_spec.json|coco") as info:
        DetectionDataset(copy)
    assert str(copy) in str(info.value) and "root:" not in str(info.value)      # nothing read from outside


@pytest.mark.parametrize("case", sorted(COCO_CASES))
def test_a_hostile_coco_file_is_refused_naming_it(copy, case):
    edit_json(copy, "coco.json", COCO_CASES[case])
    with pytest.raises(InputFileError, match="coco.json"):
        DetectionDataset(copy)


@pytest.mark.parametrize("name", ["manifest.json", "coco.json", "dataset_spec.json"])
def test_deep_nesting_and_duplicate_keys_are_refused_not_a_recursion_error(copy, name):
    (copy / name).write_text(_deep())
    with pytest.raises(InputFileError, match=name):
        DetectionDataset(copy)
    (copy / name).write_text('{"format": 1, "format": 2}')
    with pytest.raises(InputFileError, match="twice"):
        DetectionDataset(copy)


def _npz(members: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return buf.getvalue()


def test_a_frame_declaring_a_huge_array_is_refused_before_allocation(copy):
    from workbench.datasets.dataset import read_frame
    from workbench.detect.data import DetectionView
    ds = DetectionDataset(copy)
    frame = ds.frames[0].path
    huge = io.BytesIO()                           # an .npy header with no data behind it
    np.lib.format.write_array_header_1_0(huge, {"descr": "<f8", "fortran_order": False, "shape": (10 ** 9,)})
    frame.write_bytes(_npz({"irradiance.npy": huge.getvalue(), "header_json.npy": huge.getvalue()}))
    with pytest.raises(InputFileError, match="declares 8,000,000,000 bytes"):
        read_frame(frame)
    with pytest.raises(InputFileError, match=frame.name):
        DetectionView(ds, [0], "srgb")[0]
    frame.write_bytes(b"not a zip at all")
    with pytest.raises(InputFileError, match=frame.name):
        read_frame(frame)


def test_a_frame_whose_header_is_not_an_object_is_refused(copy):
    from workbench.datasets.dataset import read_frame
    ds = DetectionDataset(copy)
    frame = ds.frames[0].path
    with np.load(frame, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["header_json"] = np.asarray(json.dumps([1, 2, 3]))
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    frame.write_bytes(buf.getvalue())
    with pytest.raises(InputFileError, match="header"):
        read_frame(frame)


def test_a_hostile_results_file_is_refused_naming_it(tmp_path):
    from workbench.experiments.results import read_results
    folder = tmp_path / "res"
    folder.mkdir()
    for text in (_deep(), '{"format": "camera-workbench-experiment", "format": "x"}', "[1, 2]",
                 json.dumps({"format": "camera-workbench-experiment", "schema_version": 3, "kind": "isp",
                             "summary": [], "contrasts": [], "runs": "notalist"})):
        (folder / "results.json").write_text(text)
        with pytest.raises(InputFileError, match="results.json"):
            read_results(folder)


def test_a_frame_whose_array_header_is_cut_is_refused_not_a_tokenizer_error(tmp_path):
    """A flipped byte left an unclosed bracket in an .npy header: numpy's header parser raised
    tokenize.TokenError, which check_npz let through (found by the data-set fuzz)."""
    from workbench.datasets.files import check_npz
    header = b"{'descr': '<f4', 'fortran_order': False, 'shape': (3, "
    header += b" " * (63 - (10 + len(header)) % 64) + b"\n"
    npy = b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header + bytes(12)
    path = tmp_path / "frame_000000.npz"
    path.write_bytes(_npz({"irradiance.npy": npy}))
    with pytest.raises(InputFileError, match=r"frame_000000.npz: cannot be read as an .npz \(TokenError\)"):
        check_npz(path)

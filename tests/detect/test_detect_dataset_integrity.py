"""A data set verifies itself (issue 34, item 1): frames are checked against the sha256, shape and
scale manifest.json recorded, labels against the frames' size, the categories and the digest the
manifest recorded; every case of the issue is refused naming the file, and `dataset-verify`
lists all problems of a folder."""
from __future__ import annotations

import hashlib
import json
import os
import shutil

import numpy as np
import pytest
from frame_edits import edit_json, rewrite_frame

from workbench.datasets.dataset import frame_path, read_frame
from workbench.detect.data import DetectionDataset, DetectionView
from workbench.errors import InputFileError


def reseal(folder, index: int) -> None:
    """Record frame `index`'s present bytes in manifest.json (and the manifest's own digest), as if
    the set had been written so: the checks behind the hashes are then what refuses it."""
    from workbench.datasets.integrity import manifest_digest
    digest = hashlib.sha256(frame_path(folder, index).read_bytes()).hexdigest()

    def change(d):
        d["frames"][index]["sha256"] = digest
        d["manifest_sha256"] = manifest_digest(d)
    edit_json(folder, "manifest.json", change)


def _first_read(folder, item: int = 0):
    ds = DetectionDataset(folder)
    return DetectionView(ds, [item], "srgb")[0]


# ------------------------------------------------------------------ labels (coco.json)
def test_labels_swapped_between_two_frames_are_refused_naming_the_frame(copy):
    def swap(d):
        for a in d["annotations"]:
            a["image_id"] = {1: 2, 2: 1}.get(a["image_id"], a["image_id"])
    edit_json(copy, "coco.json", swap)
    with pytest.raises(InputFileError, match=r"coco.json: the labels of frame 0 .*swapped") as info:
        DetectionDataset(copy)
    assert "and 1 more problem: `workbench dataset-verify" in str(info.value)      # frame 1's


def test_a_reindented_coco_file_holds_the_same_labels_and_is_accepted(copy):
    (copy / "coco.json").write_text(json.dumps(json.loads((copy / "coco.json").read_text()), indent=4))
    assert len(DetectionDataset(copy).frames) == 14


def test_every_annotation_listed_twice_is_refused(copy):
    edit_json(copy, "coco.json", lambda d: d.update(annotations=d["annotations"] * 2))
    with pytest.raises(InputFileError, match=r"coco.json: annotations\[\d+\] repeats annotations\[0\]"):
        DetectionDataset(copy)


def test_an_annotation_of_an_unknown_category_is_refused(copy):
    edit_json(copy, "coco.json", lambda d: [a.update(category_id=99) for a in d["annotations"]])
    with pytest.raises(InputFileError, match=r"coco.json: annotations\[0\].category_id 99 is not one of the categories"):
        DetectionDataset(copy)


def test_a_box_outside_its_frame_is_refused(copy):
    edit_json(copy, "coco.json", lambda d: d["annotations"][0].update(bbox=[60.0, 0.0, 30.0, 10.0]))
    with pytest.raises(InputFileError, match=r"annotations\[0\].bbox .* reaches outside its 64×48 image"):
        DetectionDataset(copy)


def test_categories_renamed_are_refused(copy):
    edit_json(copy, "coco.json", lambda d: [c.update(name={"car": "bus", "bus": "car"}.get(c["name"], c["name"]))
                                        for c in d["categories"]])
    with pytest.raises(InputFileError, match=r"coco.json: its categories are not those the data set was written with"):
        DetectionDataset(copy)


def test_an_edited_manifest_is_refused(copy):
    edit_json(copy, "manifest.json", lambda d: d["project"]["isp"].update(demosaic="malvar2004"))
    with pytest.raises(InputFileError, match=r"manifest.json: its content is not what was written"):
        DetectionDataset(copy)


def test_labels_of_another_frame_size_are_refused(copy):
    edit_json(copy, "coco.json", lambda d: [im.update(width=160, height=128) for im in d["images"]])
    with pytest.raises(InputFileError, match=r"coco.json: image 1 \(frame 0\) is 160×128 px, not the frames' 64×48"):
        DetectionDataset(copy)


# ------------------------------------------------------------------ frame files
def test_a_frame_copied_over_another_is_refused_when_first_read(copy):
    shutil.copyfile(frame_path(copy, 1), frame_path(copy, 0))
    with pytest.raises(InputFileError, match=r"frame_000000.npz: its bytes are not those manifest.json recorded "
                                             r"for frame 0 .*header says frame 1.*--frames 14 --out"):
        _first_read(copy)


def test_an_edited_frame_is_refused(copy):
    path = frame_path(copy, 2)
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.raises(InputFileError, match=r"frame_000002.npz: its bytes are not those"):
        _first_read(copy, 2)


def test_a_header_whose_index_disagrees_with_the_manifest_is_refused(copy):
    shutil.copyfile(frame_path(copy, 1), frame_path(copy, 0))
    reseal(copy, 0)
    with pytest.raises(InputFileError, match=r"frame_000000.npz: its header disagrees with manifest.json \(index 1 ≠ 0"):
        _first_read(copy)


def test_a_manifest_shape_off_the_sensor_grid_is_refused(copy):
    edit_json(copy, "manifest.json", lambda d: d["frames"][3].update(irradiance_shape=[24, 32, 3]))
    with pytest.raises(InputFileError, match=r"manifest.json: frames\[3\].irradiance_shape \[24, 32, 3\] is not on"):
        DetectionDataset(copy)


def _scale(value):
    return lambda arrays, head: head.update(irradiance_scale=value)


def _irradiance(change):
    def apply(arrays, head):
        arrays["irradiance"] = change(arrays["irradiance"])
    return apply


FRAME_CASES = {
    "negative irradiance": (_irradiance(lambda a: -a), "NaN, infinite or negative"),
    "a NaN in the irradiance": (_irradiance(lambda a: np.where(np.arange(a.size).reshape(a.shape) == 7, np.nan, a)
                                            .astype(a.dtype)), "1 NaN, infinite or negative"),
    "irradiance_scale -1": (_scale(-1.0), r"irradiance_scale \('-1.0'\) must be a finite number > 0"),
    "irradiance_scale 'abc'": (_scale("abc"), r"irradiance_scale \('abc'\) must be a finite number > 0"),
    "irradiance_scale infinite": (_scale(float("inf")), "irradiance_scale"),
    "irradiance 24×32 on 48×64 labels": (_irradiance(lambda a: a[::2, ::2]), r"irradiance is 24×32 px but its label maps are 48×64"),
    "integer irradiance": (_irradiance(lambda a: a.astype(np.int32)), "H×W×bands, float16 or float32"),
}


@pytest.mark.parametrize("case", sorted(FRAME_CASES))
def test_a_frame_with_invalid_content_is_refused_naming_it(copy, case):
    change, message = FRAME_CASES[case]
    rewrite_frame(frame_path(copy, 0), change)
    with pytest.raises(InputFileError, match=f"frame_000000.npz: .*{message}"):
        read_frame(frame_path(copy, 0))
    reseal(copy, 0)                                     # behind a matching hash: the content checks refuse it
    with pytest.raises(InputFileError, match=f"frame_000000.npz: .*{message}"):
        _first_read(copy)


CHECK_NPZ = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))     # the old reader filled the memory
from workbench.datasets.files import check_npz
from workbench.errors import InputFileError
try:
    check_npz(sys.argv[1])
except InputFileError as exc:
    print(exc)
"""


def test_check_npz_refuses_a_device_or_fifo_without_reading(tmp_path):
    """In a child process with 2 GiB of address space and a time limit: the reader before this
    check read /dev/zero until memory ran out and waited on a FIFO for ever."""
    import subprocess
    import sys
    fifo = tmp_path / "fifo.npz"
    os.mkfifo(fifo)
    link = tmp_path / "zero.npz"
    link.symlink_to("/dev/zero")
    for path, kind in (("/dev/zero", "a device"), (fifo, "a FIFO"), (link, "a device")):
        out = subprocess.run([sys.executable, "-c", CHECK_NPZ, str(path)], capture_output=True, text=True,
                             timeout=60, env={**os.environ, "OMP_NUM_THREADS": "1"})
        assert out.stdout.strip() == f"{path}: is {kind}, not an .npz file; refused without reading it", out.stderr[-300:]


# ------------------------------------------------------------------ migration and resume
def _strip_hashes(folder):
    def strip(d):
        for e in d["frames"]:
            for key in ("sha256", "irradiance_shape", "irradiance_scale", "labels_sha256"):
                e.pop(key)
        for key in ("integrity", "categories_sha256", "manifest_sha256"):
            d.pop(key)
    edit_json(folder, "manifest.json", strip)


def test_a_manifest_without_hashes_is_refused_and_one_resume_run_writes_them(tmp_path):
    from workbench.detect.synthetic import make_synthetic_dataset
    folder = tmp_path / "old"
    make_synthetic_dataset(folder, frames=4)
    frames_before = {i: frame_path(folder, i).read_bytes() for i in range(4)}
    _strip_hashes(folder)
    with pytest.raises(InputFileError, match=r"manifest.json: was written before data sets recorded a sha256 per "
                                             r"frame.*`workbench dataset PROJECT --frames 4 --out .*old` with the "
                                             r"project it was rendered from \('synthetic_detection'\) once"):
        DetectionDataset(folder)
    resumed = make_synthetic_dataset(folder, frames=4)
    assert resumed.rendered == [] and resumed.reused == [0, 1, 2, 3]
    assert {i: frame_path(folder, i).read_bytes() for i in range(4)} == frames_before
    assert len(DetectionDataset(folder).frames) == 4


def test_a_resume_renders_again_a_frame_whose_bytes_changed_since_the_manifest(tmp_path):
    from workbench.detect.synthetic import make_synthetic_dataset
    folder = tmp_path / "set"
    make_synthetic_dataset(folder, frames=3)
    original = frame_path(folder, 1).read_bytes()
    rewrite_frame(frame_path(folder, 1), lambda arrays, head: head["meta"].update(f_number=2.0))
    assert read_frame(frame_path(folder, 1))[1]["index"] == 1       # still a readable frame 1
    resumed = make_synthetic_dataset(folder, frames=3)
    assert resumed.rendered == [1] and frame_path(folder, 1).read_bytes() == original


# ------------------------------------------------------------------ the commands
def test_dataset_verify_lists_every_problem_and_exits_non_zero(copy, capsys):
    from workbench.cli import main
    assert main(["dataset-verify", str(copy)]) == 0
    assert json.loads(capsys.readouterr().out) == {"folder": str(copy), "valid": True, "frames": 14}
    shutil.copyfile(frame_path(copy, 5), frame_path(copy, 4))
    edit_json(copy, "coco.json", lambda d: d["annotations"].append(d["annotations"][0]))
    rewrite_frame(frame_path(copy, 6), _scale(-1.0))
    assert main(["dataset-verify", str(copy)]) == 2
    out, err = capsys.readouterr()
    lines = out.strip().splitlines()
    assert any("repeats annotations[0]" in x for x in lines)
    assert any("frame_000004.npz: its bytes are not those" in x and "header says frame 5" in x for x in lines)
    assert any("frame_000006.npz: its bytes are not those" in x for x in lines)
    assert any("the labels of frame 0" in x for x in lines)            # the doubled annotation is frame 0's
    assert err.strip().endswith(f"{len(lines)} problems in {copy} (listed above)")


def test_dataset_stats_refuses_a_fifo_or_a_link_to_dev_zero_naming_it(copy, capsys):
    from workbench.cli import main
    for make in (lambda p: os.mkfifo(p), lambda p: p.symlink_to("/dev/zero")):
        odd = frame_path(copy, 14)
        make(odd)
        assert main(["dataset-stats", str(copy)]) == 2
        err = capsys.readouterr().err
        assert "frame_000014.npz: has a frame's name but is not a regular file" in err
        odd.unlink()
    assert main(["dataset-stats", str(copy)]) == 0

"""Per-data-set statistics (workbench.datasets.stats) against hand-counted label records,
and the files and command that write them (no renders: frames are built from label records)."""
import json
import math

import numpy as np
from PIL import Image

from workbench.cli import main
from workbench.datasets import stats as dataset_stats
from workbench.render.city_frame import FrameData
from workbench.datasets.dataset import FRAME_FORMAT, frame_path, write_folder_statistics, write_frame
from workbench.datasets.stats import dataset_statistics
from workbench.render.labels import Labels, ObjectLabel


def obj(inst, cls, h_px, visible_px, amodal_px, truncation, dist_m):
    cid = {"car": 1, "pedestrian": 2}[cls]
    return ObjectLabel(inst, cid, cls, (0, 0, 3, h_px) if visible_px else (0, 0, 0, 0), (0, 0, 3, h_px),
                       visible_px, amodal_px, 1.0 - visible_px / amodal_px, truncation > 0, truncation, dist_m)


def labels(objects):
    z = np.zeros((4, 6), np.int32)
    return Labels(z.astype(np.float32), z.astype(np.float32), z, z, objects, {1: "car", 2: "pedestrian"})


# Three frames: 3 objects, none, 2 objects (one car fully occluded, one pedestrian truncated).
FRAMES = [
    labels([obj(1, "car", 10, 40, 40, 0.0, 12.0),       # unoccluded, 10 px, 12 m
            obj(2, "car", 40, 30, 60, 0.0, 4.0),        # half occluded, 40 px, 4 m
            obj(3, "pedestrian", 20, 10, 10, 0.5, 25.0)]),   # truncated, 20 px, 25 m
    labels([]),
    labels([obj(4, "car", 5, 0, 20, 0.0, 70.0),         # fully occluded (no visible box), 70 m
            obj(5, "pedestrian", 2000, 80, 80, 0.25, 500.0)]),   # beyond the last edges
]


def test_statistics_equal_hand_counts():
    s = dataset_statistics(FRAMES)
    assert (s["frames"], s["objects"], s["visible_objects"]) == (3, 5, 4)
    assert s["objects_per_frame_mean"] == 5 / 3
    assert s["visible_objects_per_frame_mean"] == 4 / 3
    assert s["visible_objects_per_frame_histogram"] == [1, 1, 0, 1]      # frames with 0, 1, 2, 3
    assert s["occluded_fraction"] == 2 / 5 and s["fully_occluded_fraction"] == 1 / 5
    assert math.isclose(s["mean_occlusion"], (0.5 + 1.0) / 5)
    assert s["truncated_fraction"] == 2 / 5 and math.isclose(s["mean_truncation"], 0.75 / 5)
    car, ped = s["per_class"]["car"], s["per_class"]["pedestrian"]
    assert (car["objects"], car["visible_objects"], ped["objects"], ped["visible_objects"]) == (3, 2, 2, 2)
    assert car["fully_occluded_fraction"] == 1 / 3 and math.isclose(car["mean_occlusion"], 1.5 / 3)
    assert ped["truncated_fraction"] == 1.0 and car["truncated_fraction"] == 0.0
    # visible heights 10, 40, 20, 2000 px in bins [0,8,16,32,64,128,256,512,1024]; 2000 → last bin
    assert s["box_height_px"]["counts"] == [0, 1, 1, 1, 0, 0, 0, 1]
    assert s["box_height_px"]["median"] == 30.0
    # distances 12, 4, 25, 70, 500 m in bins [0,5,10,15,20,30,50,75,100,150,200]; 500 → last bin
    assert s["distance_m"]["counts"] == [1, 0, 1, 0, 1, 0, 1, 0, 0, 1]
    assert s["distance_m"]["median"] == 25.0
    interest = s["objects_of_interest"]                 # car and pedestrian are both of interest
    assert interest["objects"] == 5 and interest["visible_per_frame_histogram"] == [1, 1, 0, 1]
    cars = dataset_statistics(FRAMES, classes_of_interest=("car",))["objects_of_interest"]
    assert cars["visible_per_frame_histogram"] == [2, 0, 1] and cars["visible_per_frame_mean"] == 2 / 3
    assert (cars["objects"], cars["fully_occluded_fraction"]) == (3, 1 / 3)


def test_empty_data_set_gives_zeros_not_nan():
    for frames in ([], [labels([]), labels([])]):
        s = dataset_statistics(frames)
        flat = json.dumps(s)
        assert "NaN" not in flat and "Infinity" not in flat
        assert s["objects"] == 0 and s["occluded_fraction"] == 0.0 and s["objects_per_frame_mean"] == 0.0
        assert s["per_class"] == {} and not any(s["distance_m"]["counts"])
    assert dataset_statistics([labels([]), labels([])])["visible_objects_per_frame_histogram"] == [2]


def _folder(tmp_path):
    out = tmp_path / "set"
    (out / "frames").mkdir(parents=True)
    for i, lab in enumerate(FRAMES):
        write_frame(frame_path(out, i), FrameData(np.ones((4, 6, 1), np.float32), np.array([550.0]), lab),
                    {"format": FRAME_FORMAT, "index": i}, "float32")
    return out


def test_folder_statistics_are_written_atomically_and_plotted(tmp_path, monkeypatch):
    written = []

    def spy(path, text):
        written.append(path.name)
        return real(path, text)

    real = dataset_stats.atomic_write_text
    monkeypatch.setattr(dataset_stats, "atomic_write_text", spy)
    out = _folder(tmp_path)
    json_path, png_path = write_folder_statistics(out)
    assert written == ["statistics.json"]
    assert json.loads(json_path.read_text()) == json.loads(json.dumps(dataset_statistics(FRAMES)))
    assert Image.open(png_path).size[0] > 500
    assert not list(out.glob(".*.tmp"))


def test_dataset_stats_command(tmp_path, capsys):
    out = _folder(tmp_path)
    assert main(["dataset-stats", str(out)]) == 0
    assert json.loads(capsys.readouterr().out)["statistics"].endswith("statistics.json")
    assert main(["dataset-stats", str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "missing" in err and "does not exist" in err
    (tmp_path / "empty").mkdir()
    assert main(["dataset-stats", str(tmp_path / "empty")]) == 2
    assert "not a data-set folder" in capsys.readouterr().err


def test_dataset_stats_is_refused_while_another_command_writes_the_folder(tmp_path, capsys):
    """One writer per folder: statistics written into a set a render is still writing were refused by nobody."""
    from workbench.compute.folder_lock import hold_folder_lock
    out = _folder(tmp_path)
    with hold_folder_lock(out, "workbench dataset"):
        assert main(["dataset-stats", str(out)]) == 2
    assert "in use by" in capsys.readouterr().err
    assert main(["dataset-stats", str(out)]) == 0

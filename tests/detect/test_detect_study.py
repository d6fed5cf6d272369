"""A design study with a trained detector: each design's test mAP through its own sensor and ISP,
run on the fly over the rendered frames; designs that would need other frames are refused first."""
import json

import pytest

from workbench.detect.data import DetectionDataset
from workbench.detect.engine import TrainConfig, train_detector
from workbench.detect.synthetic import make_synthetic_dataset
from workbench.errors import WorkbenchError
from workbench.jobs import run_job
from workbench.metrics.study import run_study


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    folder = tmp_path_factory.mktemp("study_set")
    make_synthetic_dataset(folder, frames=18, rows=96, cols=128)      # 3 cities of 6 poses: the third is a test city
    config = TrainConfig(net="mobile", representation="srgb", epochs=2, batch_size=4, threads=1, device="cpu",
                         curve_points=0)
    train_detector(DetectionDataset(folder), config, folder / "net.pt")
    return folder, folder / "net.pt"


def test_study_reports_map_per_design(trained, tmp_path):
    folder, ckpt = trained
    project = DetectionDataset(folder).project
    doc = run_job(run_study(project, {"sensor.read_noise_V": [0.001, 0.02]}, tmp_path / "s", y="map",
                            detector=ckpt, data=folder))
    maps = [d["summary"]["map"] for d in doc["designs"]]
    assert len(maps) == 2 and all(m is None or 0.0 <= m <= 1.0 for m in maps)
    assert all(d["detection"]["test_images"] == len(DetectionDataset(folder).indices("test")) for d in doc["designs"])
    assert "map" in (tmp_path / "s" / "study.md").read_text()
    assert json.loads((tmp_path / "s" / "study.json").read_text())["detector"] == str(ckpt.resolve())


def test_a_study_of_a_set_without_a_test_city_is_refused(tmp_path):
    """10 frames are 2 cities, both training cities: the bootstrap of no test frames divided by zero."""
    from workbench.errors import InputFileError
    from workbench.metrics.detection import design_map
    folder = tmp_path / "small"
    make_synthetic_dataset(folder, frames=10, rows=48, cols=64)
    with pytest.raises(InputFileError, match="no test frames.*at least 3 cities"):
        design_map(DetectionDataset(folder).project, tmp_path / "none.pt", folder)


def test_study_refuses_designs_that_need_other_frames_before_measuring(trained, tmp_path):
    folder, ckpt = trained
    project = DetectionDataset(folder).project
    with pytest.raises(WorkbenchError, match="rows|cols|pixel|frames"):
        run_job(run_study(project, {"sensor.rows": [48, 96]}, tmp_path / "s", detector=ckpt, data=folder))
    assert not (tmp_path / "s").exists()

"""`workbench render` and `workbench dataset` end to end, with the tiny renderer standing in for
the city renderer (same FrameData contract)."""
import json

import numpy as np
from labels_helpers import H, W, tiny_renderer
from PIL import Image

from workbench.cli import main
from workbench.project import Project, save_project
from workbench.datasets import dataset
from workbench.render import city_frame
from workbench.datasets.dataset import read_frame


def test_render_command_writes_previews_arrays_and_coco(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(city_frame, "render_city_frame",
                        lambda project, seeds, on_progress=None: tiny_renderer(project, seeds))
    save_project(Project(seed=3), tmp_path / "p.json")
    assert main(["render", str(tmp_path / "p.json"), "--out", str(tmp_path / "out"), "--frame", "2"]) == 0
    out = tmp_path / "out"
    preview = np.asarray(Image.open(out / "frame_000002_irradiance.png"))
    overlay = np.asarray(Image.open(out / "frame_000002_labels.png"))
    assert preview.shape == overlay.shape == (H, W, 3) and preview.std() > 0
    frame, head = read_frame(out / "frame_000002.npz")
    assert head["seeds"] == json.loads(json.dumps(city_frame.frame_seeds(3, 2).__dict__))
    # Boxes are drawn: the overlay differs from the preview on some box edge pixel.
    car = next(o for o in frame.labels.objects if o.class_name == "car" and o.visible_px)
    x, y, w, h = car.bbox_xywh
    assert np.any(overlay[y:y + h, x] != preview[y:y + h, x])
    coco = json.loads((out / "frame_000002_coco.json").read_text())
    assert coco["images"][0]["file_name"] == "frame_000002.npz" and coco["annotations"]
    report = json.loads(capsys.readouterr().out)
    assert report["visible_objects"]["car"] >= 1


def test_dataset_command_runs_and_resumes(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(dataset, "render_city_frame", tiny_renderer)
    save_project(Project(seed=4), tmp_path / "p.json")
    args = ["dataset", str(tmp_path / "p.json"), "--frames", "2", "--out", str(tmp_path / "d"),
            "--workers", "0"]
    assert main(args) == 0
    first = json.loads(capsys.readouterr().out)
    assert first["rendered"] == 2 and first["reused"] == 0
    assert main(args[:3] + ["3"] + args[4:]) == 0              # grow the set to 3 frames
    second = json.loads(capsys.readouterr().out)
    assert second["rendered"] == 1 and second["reused"] == 2
    manifest = json.loads((tmp_path / "d" / "manifest.json").read_text())
    assert len(manifest["frames"]) == 3 and manifest["irradiance"]["dtype"] == "float16"
    stats = json.loads((tmp_path / "d" / "statistics.json").read_text())   # written as the set finishes
    assert stats["frames"] == 3 and stats["objects"] == sum(f["objects"] for f in manifest["frames"])
    assert (tmp_path / "d" / "statistics.png").is_file()
    assert main(["dataset", str(tmp_path / "p.json"), "--frames", "0", "--out", str(tmp_path / "e")]) == 2


def test_dataset_command_reports_a_failed_frame_and_keeps_the_others(tmp_path, monkeypatch, capsys):
    def flaky(project, seeds):
        if seeds.index == 1:
            raise ValueError("material 'x' is defined on 400–700 nm")
        return tiny_renderer(project, seeds)
    monkeypatch.setattr(dataset, "render_city_frame", flaky)
    save_project(Project(seed=6), tmp_path / "p.json")
    rc = main(["dataset", str(tmp_path / "p.json"), "--frames", "2", "--out", str(tmp_path / "d"),
               "--workers", "0"])
    err = capsys.readouterr().err
    assert rc == 1 and "frame 1 failed" in err and "400–700 nm" in err
    assert dataset.frame_path(tmp_path / "d", 0).exists()
    assert not (tmp_path / "d" / "manifest.json").exists()

"""Data views: reproducible captures per (frame, epoch), the paper's EV rule, equal EV shares in a
mix, the split by frame seed, the label rule, and errors that name the bad file."""
import json
import shutil

import numpy as np
import pytest

from workbench.detect.boxes import keep_box
from workbench.detect.data import TEST_FRACTION, DetectionDataset, DetectionView, split_of
from workbench.errors import InputFileError, ParameterError
from workbench.sensor import irradiance_to_signal_rate


def test_same_seed_and_epoch_give_the_same_capture(synthetic_dir):
    ds = DetectionDataset(synthetic_dir)
    train = ds.indices("train")
    a = DetectionView(ds, train, "srgb", seed=3)
    b = DetectionView(ds, train, "srgb", seed=3)
    x0, t0 = a[1]
    assert np.array_equal(x0.numpy(), b[1][0].numpy())
    b.set_epoch(1)
    assert not np.array_equal(x0.numpy(), b[1][0].numpy())          # a new capture every epoch
    assert not np.array_equal(x0.numpy(), DetectionView(ds, train, "srgb", seed=4)[1][0].numpy())
    assert t0["frame"] == ds.frames[train[1]].index


@pytest.mark.parametrize("ev", [-4.0, 0.0, 2.5])
def test_exposure_is_auto_exposure_times_two_to_the_ev(synthetic_dir, ev):
    ds = DetectionDataset(synthetic_dir)
    view = DetectionView(ds, ds.indices("test"), "raw", (ev,))
    _, target = view[0]
    from workbench.detect.data import load_signal_rates
    rec = view.frame_record(0)
    rate = load_signal_rates(rec, view.sensor, ds.fingerprint)[0]
    s = view.sensor
    t_auto = target["exposure_s"] / 2.0 ** ev
    mean_v = (rate.mean(dtype=np.float64) + s.dark_current_e_per_s) * s.conversion_gain_V_per_e * t_auto
    assert mean_v == pytest.approx(0.4 * s.voltage_swing_V, rel=1e-5)   # 'mean' at 0.4 of the swing
    assert s.auto_exposure_method == "mean"


def test_the_mirror_is_taken_before_the_cfa(synthetic_dir):
    from workbench.detect.data import load_signal_rates
    from workbench.render.city_frame import frame_optical_image
    from workbench.datasets.dataset import read_frame
    ds = DetectionDataset(synthetic_dir)
    view = DetectionView(ds, ds.indices("train"), "raw")
    rec = view.frame_record(0)
    rate, mirrored = load_signal_rates(rec, view.sensor, ds.fingerprint)
    oi = frame_optical_image(read_frame(rec.path)[0])
    oi.irradiance_photons = oi.irradiance_photons[:, ::-1].copy()
    assert np.array_equal(mirrored, irradiance_to_signal_rate(oi, view.sensor))
    assert not np.array_equal(mirrored, rate[:, ::-1])          # flipping the mosaic would swap CFA colours


def test_an_ev_mix_gives_every_ev_an_equal_share_each_epoch(synthetic_dir):
    ds = DetectionDataset(synthetic_dir)
    positions = (ds.indices("train") * 3)[:9]
    view = DetectionView(ds, positions, "srgb", (-1.0, 0.0, 1.0), seed=1)
    for epoch in range(3):
        view.set_epoch(epoch)
        evs = [view[i][1]["ev"] for i in range(len(view))]
        assert sorted(evs) == [-1.0] * 3 + [0.0] * 3 + [1.0] * 3


def test_training_crops_keep_the_cfa_phase_and_move_the_boxes(synthetic_dir):
    from workbench.detect.boxes import clip_boxes, crop_boxes, mirror_boxes
    from workbench.detect.data import load_signal_rates
    from workbench.detect.representations import packed_sites
    ds = DetectionDataset(synthetic_dir)
    view = DetectionView(ds, ds.indices("train"), "raw", augment=True, crop_hw=(32, 40), seed=2)
    h, w = ds.image_hw
    mirrored_seen = False
    for i in range(len(view)):
        x, t = view[i]
        r0, c0 = t["window"]
        assert tuple(x.shape) == (4, 16, 20) and r0 % 2 == 0 and c0 % 2 == 0       # packed raw of a 32×40 window
        rec = view.frame_record(i)
        boxes, ignored = rec.boxes_xyxy, rec.ignored_xyxy
        rate = load_signal_rates(rec, view.sensor, ds.fingerprint)[int(t["mirrored"])]
        if t["mirrored"]:
            boxes, ignored, mirrored_seen = mirror_boxes(boxes, w), mirror_boxes(ignored, w), True
        kept, kept_cls, _, lost, _ = crop_boxes(boxes, rec.classes, rec.truncation, r0, c0, 32, 40, h)
        np.testing.assert_array_equal(t["boxes_xyxy"].numpy(), kept)
        np.testing.assert_array_equal(t["classes"].numpy(), kept_cls)
        assert len(t["ignored_xyxy"]) == len(clip_boxes(ignored, rec.ignored_classes, r0, c0, 32, 40)[0]) + len(lost)
        # each packed plane holds its CFA site: plane means follow the noise-free rates of those sites
        window = rate[r0:r0 + 32, c0:c0 + 40]
        expected = np.array([window[r::2, c::2].mean() for r, c in packed_sites(view.sensor.cfa_pattern)])
        got = x.numpy().reshape(4, -1).mean(axis=1)
        np.testing.assert_allclose(got / got.sum(), expected / expected.sum(), rtol=0.05)
    assert mirrored_seen


def test_a_crop_turns_a_cut_road_user_into_an_ignored_box_not_background():
    from workbench.detect.boxes import crop_boxes
    boxes = np.array([[10, 10, 30, 70], [100, 20, 120, 90]], np.float32)    # 20×60 px each
    kept, cls, trunc, lost, lost_cls = crop_boxes(boxes, np.array([0, 1]), np.array([0.0, 0.3], np.float32),
                                                  0, 20, 128, 96, 240)
    # box 0 keeps half its width: truncation 0.5, still kept; box 1 keeps 16 of 20 columns, but was
    # 30 % outside the frame already: 1 − 0.7·0.8 = 0.44 → kept
    np.testing.assert_allclose(kept, [[0, 10, 10, 70], [80, 20, 96, 90]])
    np.testing.assert_allclose(trunc, [0.5, 0.44], rtol=1e-6)
    kept, _, _, lost, lost_cls = crop_boxes(boxes, np.array([0, 1]), np.array([0.0, 0.3], np.float32), 0, 22, 128, 94, 240)
    assert len(kept) == 1 and lost_cls.tolist() == [0]                   # 8 of 20 columns: 60 % cut, ignored
    np.testing.assert_allclose(lost, [[0, 10, 8, 70]])
    boxes = np.array([[10, 10, 30, 70], [100, 70, 120, 90]], np.float32)
    kept, _, _, lost, _ = crop_boxes(boxes, np.array([0, 1]), np.zeros(2, np.float32), 60, 0, 128, 320, 240)
    np.testing.assert_allclose(kept, [[100, 10, 120, 30]])
    np.testing.assert_allclose(lost, [[10, 0, 30, 10]])                 # box 0 left 10 rows tall (< 16): ignored


def test_crop_windows_hold_the_centre_of_a_kept_box():
    from workbench.detect.boxes import crop_corner
    rng = np.random.default_rng(0)
    boxes = np.array([[290.0, 200.0, 318.0, 238.0]], np.float32)       # near the bottom-right corner
    for _ in range(200):
        r0, c0 = crop_corner(boxes, (240, 320), (128, 160), rng)
        assert r0 % 2 == 0 and c0 % 2 == 0 and 0 <= r0 <= 112 and 0 <= c0 <= 160
        assert c0 <= 304 < c0 + 160 and r0 <= 219 < r0 + 128
    corners = {crop_corner(np.zeros((0, 4), np.float32), (240, 320), (128, 160), rng) for _ in range(200)}
    assert len(corners) > 50


def test_split_puts_every_third_city_in_the_test_set():
    seeds = [{"index": i, "city": i // 6} for i in range(612)]
    splits = [split_of(s) for s in seeds]
    for c in range(102):                                           # a city is wholly train or test
        assert len(set(splits[6 * c:6 * c + 6])) == 1
    assert splits.count("test") == 204 and splits.count("train") == 408
    assert [split_of({"index": c, "city": c}) for c in range(6)] == ["train", "train", "test"] * 2
    for n in range(1, 300):                                        # exactly ⌊n·f⌋ of the first n cities
        assert sum(split_of({"index": c}) == "test" for c in range(n)) == int(n * TEST_FRACTION + 1e-9)


def test_split_and_stats_of_a_data_set(synthetic_dir):
    ds = DetectionDataset(synthetic_dir)
    train, test = ds.indices("train"), ds.indices("test")
    assert sorted(train + test) == list(range(len(ds.frames))) and train and test
    stats = ds.stats()
    assert stats["frames"] == 14 and set(stats["classes"]) <= {"car", "pedestrian", "bus", "truck"}
    assert stats["classes"]["pedestrian"]["ignored"] >= 14        # every frame has one 3 px pedestrian


def test_a_data_set_is_split_by_the_city_its_manifest_names(tmp_path):
    """The manifest's seeds name each frame's city; the reader dropped that key, so a set of several
    poses per city was split by frame index and every city had frames in both splits."""
    from workbench.detect.synthetic import make_synthetic_dataset
    make_synthetic_dataset(tmp_path / "set", frames=18)                 # 3 cities of 6 poses
    ds = DetectionDataset(tmp_path / "set")
    assert [f.seeds["city"] for f in ds.frames] == [i // 6 for i in range(18)]
    assert [f.split for f in ds.frames] == ["train"] * 12 + ["test"] * 6


def test_label_rule():
    rows = 240
    assert keep_box({"bbox": [0, 0, 6, 16], "occlusion": 0.0, "truncation": 0.0}, rows)
    assert not keep_box({"bbox": [0, 0, 6, 15], "occlusion": 0.0, "truncation": 0.0}, rows)   # < 1/15 of rows
    assert not keep_box({"bbox": [0, 0, 3, 40], "occlusion": 0.0, "truncation": 0.0}, rows)   # too narrow
    assert not keep_box({"bbox": [0, 0, 9, 40], "occlusion": 0.85, "truncation": 0.0}, rows)
    assert not keep_box({"bbox": [0, 0, 9, 40], "occlusion": 0.0, "truncation": 0.6}, rows)


def _copy(src, tmp_path):
    dst = tmp_path / "set"
    shutil.copytree(src, dst)
    return dst


def test_missing_folder_is_named(tmp_path):
    with pytest.raises(InputFileError, match="no-such-set"):
        DetectionDataset(tmp_path / "no-such-set")


def test_half_written_set_names_the_missing_manifest(synthetic_dir, tmp_path):
    folder = _copy(synthetic_dir, tmp_path)
    (folder / "manifest.json").unlink()
    with pytest.raises(InputFileError, match="manifest.json.*half-written"):
        DetectionDataset(folder)


def test_missing_frame_file_is_named(synthetic_dir, tmp_path):
    folder = _copy(synthetic_dir, tmp_path)
    (folder / "frames" / "frame_000003.npz").unlink()
    with pytest.raises(InputFileError, match="frame_000003.npz"):
        DetectionDataset(folder)


def test_another_schema_is_named(synthetic_dir, tmp_path):
    folder = _copy(synthetic_dir, tmp_path)
    spec = json.loads((folder / "dataset_spec.json").read_text())
    (folder / "dataset_spec.json").write_text(json.dumps({**spec, "format": "someone-elses-dataset"}))
    with pytest.raises(InputFileError, match="dataset_spec.json.*another schema"):
        DetectionDataset(folder)
    (folder / "dataset_spec.json").write_text("{not json")
    with pytest.raises(InputFileError, match="dataset_spec.json"):
        DetectionDataset(folder)


def test_a_damaged_frame_is_named_when_read(synthetic_dir, tmp_path):
    folder = _copy(synthetic_dir, tmp_path)
    ds = DetectionDataset(folder)
    view = DetectionView(ds, ds.indices("train"), "srgb")
    path = view.frame_record(0).path
    path.write_bytes(path.read_bytes()[:200])                      # a half-written file
    with pytest.raises(InputFileError, match=path.name):
        view[0]


def test_a_project_that_renders_other_frames_is_refused(synthetic_dir):
    from workbench.detect.synthetic import synthetic_project
    project = synthetic_project()
    DetectionDataset(synthetic_dir, project=project.updated(sensor=project.sensor.updated(read_noise_V=0.01)))
    with pytest.raises(ParameterError, match="pose"):
        DetectionDataset(synthetic_dir, project=project.updated(pose=project.pose.updated(height_m=2.0)))

"""Detection data views over a `workbench dataset` folder: sensor + ISP run on the fly from the
stored irradiance, at a chosen representation and exposure bias, with no re-render.

Exposure (the paper's rule): t = t_auto · 2^EV, t_auto from the experiment's auto-exposure method
('mean': mean pixel voltage at 0.4 of the swing) on the whole noise-free frame, limited to the
sensor's max_exposure_s. The frames keep the daylight illuminance they were rendered with (the
paper fixed 1000 lux); auto-exposure makes the mean signal the same either way, only the dark
current's share (10 e⁻/s here, < 0.1 e⁻ at these millisecond exposures) would differ.

Noise: frame f in epoch e of a view with seed s is exposed with the generator
default_rng([s, f, e, round(1000·EV)]): a run is reproducible, every epoch a new capture.
Test views use epoch 0 and a fixed seed, so every network is tested on the same captures.
Mirror and crop come from their own generator, default_rng([s, f, e, AUGMENT_TAG]), which does
not read the EV or the representation: runs of one seed see every frame with the same mirror and
window in every epoch whatever their condition (paired augmentation).

Split (`split_of`): the frames of one city arrangement (FrameSeeds.city, K consecutive frames
with pose.poses_per_arrangement = K) are all train or all test, so no city is seen in both: city
c is a test city when ⌊(c + 1)·f⌋ > ⌊c·f⌋, f = TEST_FRACTION = ⅓ (every third city, 2, 5, 8, …):
exactly ⌊n·f⌋ of the first n cities, fixed per city, so growing a set keeps the split. Frames
written before cities were numbered count as one city each (their index).

Labels: classes car, pedestrian, bus and truck (a class is used only when the training frames
hold a kept box of it); which boxes are kept and which ignored is the rule of
workbench.detect.boxes, for evaluation and training alike.

Augmentation (training views): the scene is mirrored before the sensor (the irradiance is flipped,
then sampled by the same CFA, so the mosaic stays physically right: exact where flipping the
packed mosaic would shift colours by a pixel) and a crop_hw window is cut from the signal rate at
even row/column offsets (the CFA phase is kept), placed to hold the centre of a kept box drawn at
random; the exposure still comes from the whole frame. A crop applies the label rule to what it
leaves of each box (boxes.crop_boxes). Crops cut before the sensor make sensor + ISP cost only
the window.
"""
from __future__ import annotations

import math
import time
from collections import OrderedDict
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from workbench.datasets.files import FrameEntry
from workbench.datasets.integrity import index_problems, raise_first, read_index, read_verified_frame
from workbench.detect.boxes import clip_boxes, crop_boxes, crop_corner, keep_box, mirror_boxes
from workbench.errors import InputFileError, ParameterError, WorkbenchError
from workbench.datasets.stats import CLASSES_OF_INTEREST

DETECT_CLASSES = CLASSES_OF_INTEREST            # the road users the data statistics count too
TEST_FRACTION = 1.0 / 3.0
AUGMENT_TAG = 0x61756700                # 'aug': the mirror and crop stream, the same at every EV
TEST_NOISE_SEED = 0x74657374           # 'test': the seed of every test view's captures


def split_of(seeds: dict, test_fraction: float = TEST_FRACTION) -> str:
    """'test' or 'train' for a frame, from its city number only (see the module docstring)."""
    city = int(seeds.get("city", seeds["index"]))
    return "test" if math.floor((city + 1) * test_fraction) > math.floor(city * test_fraction) else "train"


def _check_same_frames(project, rendered, manifest_path: Path) -> None:
    """ParameterError unless `project` makes the same frames as `rendered` (the data set's)."""
    from workbench.render.city_frame import frame_input_differences
    differ = frame_input_differences(project, rendered)
    if differ:
        raise ParameterError("project", project.name, f"a project that renders the frames of {manifest_path.parent} "
                             f"('{rendered.name}'); these settings differ: {', '.join(differ)}")


@dataclass(frozen=True)
class FrameRecord:
    """One frame's file, seeds, split and boxes (x0, y0, x1, y1 in pixels; classes index
    DetectionDataset.class_names), kept (with their truncation, 0…1) and ignored; its manifest
    entry (what the file must hold) and the command that renders it again."""

    index: int
    path: Path
    seeds: dict
    split: str
    boxes_xyxy: np.ndarray
    classes: np.ndarray
    truncation: np.ndarray
    ignored_xyxy: np.ndarray
    ignored_classes: np.ndarray
    entry: FrameEntry
    rerender_hint: str


def _xyxy(anns: list[dict]) -> np.ndarray:
    return np.asarray([[a["bbox"][0], a["bbox"][1], a["bbox"][0] + a["bbox"][2], a["bbox"][1] + a["bbox"][3]]
                       for a in anns], dtype=np.float32).reshape(-1, 4)


def _class_indices(anns: list[dict], cat_names: dict, cls_index: dict) -> np.ndarray:
    return np.asarray([cls_index[cat_names[int(a["category_id"])]] for a in anns], np.int64)


class DetectionDataset:
    """A finished `workbench dataset` folder read for detection: the project it was rendered from,
    frame records with the label rule applied, and the train/test split.

    project: the project whose sensor, ISP and experiment settings the views use (default the one
    the frames were rendered from); its frame settings (datasets.dataset.FRAME_PROJECT_SECTIONS and
    the sensor's grid and channels) must be the data set's.
    Raises InputFileError naming the file when the folder is missing, half-written (no
    manifest.json / coco.json, or a listed frame absent), of another format or version, or when
    its labels are not those the manifest recorded or do not fit its frames and categories
    (datasets.integrity); each frame is verified when a view first reads it."""

    def __init__(self, folder: str | Path, classes: tuple[str, ...] = DETECT_CLASSES,
                 test_fraction: float = TEST_FRACTION, project=None):
        index = read_index(folder)
        self.folder = index.folder
        raise_first(index_problems(index), self.folder)
        self.project = index.project
        if project is not None:
            _check_same_frames(project, self.project, index.manifest_path)
            self.project = project
        self.fingerprint = index.fingerprint
        self.rerender_hint = index.rerender_hint
        cat_names, images, anns_of = index.categories, index.images, index.annotations
        self.image_hw = (self.project.sensor.rows, self.project.sensor.cols)
        rows = self.image_hw[0]
        present = {cat_names.get(int(a["category_id"])) for anns in anns_of.values() for a in anns
                   if keep_box(a, rows)}
        self.class_names = tuple(c for c in classes if c in present) or tuple(classes)
        cls_index = {c: k for k, c in enumerate(self.class_names)}
        self.frames: list[FrameRecord] = []
        for entry in index.entries:
            image = images[entry.index]
            anns = [a for a in anns_of.get(int(image["id"]), []) if cat_names.get(int(a["category_id"])) in cls_index]
            kept = [a for a in anns if keep_box(a, rows)]
            ignored = [a for a in anns if not keep_box(a, rows)]
            self.frames.append(FrameRecord(entry.index, entry.path, entry.seeds, split_of(entry.seeds, test_fraction),
                                           _xyxy(kept), _class_indices(kept, cat_names, cls_index),
                                           np.asarray([a.get("truncation", 0.0) for a in kept], np.float32),
                                           _xyxy(ignored), _class_indices(ignored, cat_names, cls_index),
                                           entry, index.rerender_hint))

    @property
    def split_digest(self) -> str:
        """A digest of which frames are test frames: part of a run's identity (a run trained or tested
        on other frames is another run)."""
        import hashlib
        test = [f.index for f in self.frames if f.split == "test"]
        return hashlib.sha256(",".join(map(str, test)).encode()).hexdigest()[:16]

    def test_indices(self) -> list[int]:
        """indices('test'), refused when there are none (a set of fewer than three cities): a test
        mAP of no frames is no number."""
        test = self.indices("test")
        if not test:
            per_city = self.project.pose.poses_per_arrangement if self.project.pose is not None else 1
            raise InputFileError(self.folder, f"holds no test frames: every third city is a test city (cities 2, 5, "
                                              f"…), so render at least 3 cities ({3 * per_city} frames with "
                                              f"{per_city} pose(s) a city)")
        return test

    def indices(self, split: str) -> list[int]:
        """Positions (into self.frames) of the 'train' or 'test' frames."""
        if split not in ("train", "test"):
            raise ParameterError("split", split, "one of 'train', 'test'")
        return [k for k, f in enumerate(self.frames) if f.split == split]

    def stats(self) -> dict:
        """Frames per split and kept/ignored objects per class (and per frame)."""
        out = {"frames": len(self.frames), "train": len(self.indices("train")),
               "test": len(self.indices("test")), "image_hw": list(self.image_hw), "classes": {}}
        for k, name in enumerate(self.class_names):
            kept = sum(int((f.classes == k).sum()) for f in self.frames)
            out["classes"][name] = {"kept": kept, "ignored": sum(int((f.ignored_classes == k).sum())
                                                                 for f in self.frames)}
        kept_total = sum(len(f.classes) for f in self.frames)
        out["kept_per_frame"] = kept_total / len(self.frames)
        out["ignored_per_frame"] = sum(len(f.ignored_classes) for f in self.frames) / len(self.frames)
        return out


def load_signal_rates(record: FrameRecord, sensor, fingerprint: str) -> tuple[np.ndarray, np.ndarray]:
    """(rate, mirrored-scene rate): mean e⁻/s per pixel of the frame and of its mirror image
    (irradiance flipped left-right before the CFA samples it). The frame is verified against the
    manifest as it is read (datasets.integrity.read_verified_frame); errors name the frame file."""
    from workbench.render.city_frame import frame_optical_image
    from workbench.sensor import irradiance_to_signal_rate

    data, _ = read_verified_frame(record.entry, fingerprint, record.rerender_hint)
    try:
        oi = frame_optical_image(data)
        mirrored = replace(oi, irradiance_photons=np.ascontiguousarray(oi.irradiance_photons[:, ::-1]), depth_m=None)
        return irradiance_to_signal_rate(oi, sensor), irradiance_to_signal_rate(mirrored, sensor)
    except WorkbenchError as exc:
        raise InputFileError(record.path, f"frame {record.index} cannot be used as a frame of this data set: {exc}; "
                                          f"{record.rerender_hint}") from None


class RateCache:
    """Least-recently-used cache of per-frame signal rates, bounded in MB (RATES: the one cache
    of a process, shared by every view and run in it)."""

    def __init__(self, limit_mb: float):
        self.limit_bytes = int(limit_mb * 2 ** 20)
        self._items: OrderedDict = OrderedDict()
        self._bytes = 0

    def set_limit(self, limit_mb: float) -> None:
        self.limit_bytes = int(limit_mb * 2 ** 20)

    def get(self, key, make):
        if key in self._items:
            self._items.move_to_end(key)
            return self._items[key]
        value = make()
        size = sum(a.nbytes for a in value)
        if size <= self.limit_bytes:
            self._items[key] = value
            self._bytes += size
            while self._bytes > self.limit_bytes:
                _, old = self._items.popitem(last=False)
                self._bytes -= sum(a.nbytes for a in old)
        return value


RATES = RateCache(1024.0)


def experiment_sensor(project):
    """The project's sensor with the experiment's auto-exposure (method, level) and no EV bias."""
    exp = project.experiment
    return project.sensor.updated(exposure_s=None, ev_bias=0.0, auto_exposure_method=exp.auto_exposure_method,
                                  auto_exposure_level=exp.auto_exposure_level)


class DetectionView:
    """A torch-style Dataset (len, getitem) of network inputs and box targets.

    dataset: DetectionDataset; positions: indices into dataset.frames; representation: 'raw',
    'linear' or 'srgb'; evs: one EV bias, or several for an EV mix (every epoch each EV is given
    to an equal share of the frames, by a seeded permutation); seed: noise and augmentation seed;
    augment: mirror the scene with probability ½ and cut crop_hw windows (training);
    cache_mb: the limit of the process's signal-rate cache (RATES). A key is an item number (in the epoch set by
    set_epoch) or an (item, epoch) pair, so loader worker processes need no epoch state.
    Item: (input C×h×w float32 tensor, target dict with boxes_xyxy, classes, ignored_xyxy,
    ignored_classes, frame index, ev, exposure_s, sensor_isp_s, window (row, col of the crop's
    corner) and mirrored). `timing` sums seconds spent
    loading and in sensor + ISP in this process."""

    def __init__(self, dataset: DetectionDataset, positions, representation: str, evs=(0.0,), *,
                 seed: int = TEST_NOISE_SEED, augment: bool = False, crop_hw: tuple[int, int] | None = None,
                 cache_mb: float = 1024.0):
        from workbench.detect.representations import REPRESENTATIONS
        if representation not in REPRESENTATIONS:
            raise ParameterError("representation", representation, f"one of {', '.join(REPRESENTATIONS)}")
        evs = tuple(float(e) for e in np.atleast_1d(evs))
        if not evs or not all(np.isfinite(evs)) or any(abs(e) > 16 for e in evs):
            raise ParameterError("evs", evs, "one or more finite EV biases in −16…16")
        h, w = dataset.image_hw
        if crop_hw is not None and not (crop_hw[0] % 4 == 0 and crop_hw[1] % 4 == 0
                                        and 0 < crop_hw[0] <= h and 0 < crop_hw[1] <= w):
            raise ParameterError("crop_hw", crop_hw, f"multiples of 4 no larger than the {h}×{w} frames")
        self.dataset, self.positions = dataset, list(positions)
        self.representation, self.evs, self.seed = representation, evs, int(seed)
        self.augment, self.crop_hw = augment, crop_hw
        self.sensor = experiment_sensor(dataset.project)
        self._sensors = {(h, w): self.sensor}
        RATES.set_limit(cache_mb)
        self._rate_key = (str(dataset.folder), dataset.fingerprint, self.sensor.model_dump_json())
        self._exposure: dict[int, float] = {}
        self.epoch = 0
        self._ev_by_epoch: dict[int, np.ndarray] = {}
        self.timing = {"load_s": 0.0, "sensor_isp_s": 0.0, "items": 0}
        wl = dataset.project.scene.wavelengths
        self._qe_wl = np.arange(wl.start_nm, wl.stop_nm + 0.5 * wl.step_nm, wl.step_nm)

    def __len__(self) -> int:
        return len(self.positions)

    def set_epoch(self, epoch: int) -> None:
        """The epoch that integer keys use (a key may also be an (item, epoch) pair)."""
        self.epoch = int(epoch)

    def _ev_of(self, item: int, epoch: int) -> float:
        if epoch not in self._ev_by_epoch:
            order = np.random.default_rng([self.seed, epoch, 0x6576]).permutation(len(self.positions))
            evs = np.empty(len(self.positions))
            evs[order] = np.resize(np.asarray(self.evs), len(self.positions))
            self._ev_by_epoch = {epoch: evs}
        return float(self._ev_by_epoch[epoch][item])

    def _sensor_for(self, h: int, w: int):
        if (h, w) not in self._sensors:
            self._sensors[(h, w)] = self.sensor.updated(rows=h, cols=w)
        return self._sensors[(h, w)]

    def frame_record(self, item: int) -> FrameRecord:
        return self.dataset.frames[self.positions[item]]

    def __getitem__(self, key):
        import torch

        from workbench.detect.representations import network_input
        from workbench.isp import sensor_image_to_srgb
        from workbench.sensor import auto_exposure, signal_rate_to_sensor_image

        item, epoch = key if isinstance(key, tuple) else (key, self.epoch)
        rec = self.frame_record(item)
        ev = self._ev_of(item, epoch)
        t0 = time.perf_counter()
        rates = RATES.get((*self._rate_key, rec.index),
                          lambda: load_signal_rates(rec, self.sensor, self.dataset.fingerprint))
        t1 = time.perf_counter()
        if rec.index not in self._exposure:
            self._exposure[rec.index] = float(auto_exposure(rates[0], self.sensor))
        exposure_s = min(self._exposure[rec.index] * 2.0 ** ev, self.sensor.max_exposure_s)
        rng = np.random.default_rng([self.seed, rec.index, epoch, int(round(1000 * ev)) & 0xFFFFFFFF])
        augment_rng = np.random.default_rng([self.seed, rec.index, epoch, AUGMENT_TAG])
        h, w = self.dataset.image_hw
        boxes, classes = rec.boxes_xyxy, rec.classes
        ignored, ignored_cls = rec.ignored_xyxy, rec.ignored_classes
        mirrored = bool(self.augment and augment_rng.random() < 0.5)
        rate = rates[int(mirrored)]
        if mirrored:
            boxes, ignored = mirror_boxes(boxes, w), mirror_boxes(ignored, w)
        r0 = c0 = 0
        if self.crop_hw is not None:
            ch, cw = self.crop_hw
            r0, c0 = crop_corner(boxes, (h, w), (ch, cw), augment_rng)
            rate = rate[r0:r0 + ch, c0:c0 + cw]
            ignored, ignored_cls = clip_boxes(ignored, ignored_cls, r0, c0, ch, cw)
            boxes, classes, _, lost, lost_cls = crop_boxes(boxes, classes, rec.truncation, r0, c0, ch, cw, h)
            ignored, ignored_cls = np.concatenate([ignored, lost]), np.concatenate([ignored_cls, lost_cls])
        image = signal_rate_to_sensor_image(np.ascontiguousarray(rate), self._sensor_for(*rate.shape), exposure_s, rng,
                       wavelengths_nm=self._qe_wl)
        isp = None if self.representation == "raw" else sensor_image_to_srgb(image, self.dataset.project.isp)
        x = network_input(image, isp, self.representation)
        t2 = time.perf_counter()
        self.timing["load_s"] += t1 - t0
        self.timing["sensor_isp_s"] += t2 - t1
        self.timing["items"] += 1
        target = {"boxes_xyxy": torch.from_numpy(np.ascontiguousarray(boxes)),
                  "classes": torch.from_numpy(np.ascontiguousarray(classes)),
                  "ignored_xyxy": torch.from_numpy(np.ascontiguousarray(ignored)),
                  "ignored_classes": torch.from_numpy(np.ascontiguousarray(ignored_cls)),
                  "frame": rec.index, "ev": ev, "exposure_s": exposure_s, "sensor_isp_s": t2 - t1,
                  "window": (r0, c0), "mirrored": mirrored}
        return torch.as_tensor(np.ascontiguousarray(x)), target


def batches(n: int, batch_size: int, rng: np.random.Generator | None, epoch: int = 0):
    """Batches of (item, epoch) keys: a seeded permutation (rng) or the items in order."""
    order = rng.permutation(n) if rng is not None else np.arange(n)
    return [[(int(i), epoch) for i in order[k:k + batch_size]] for k in range(0, n, batch_size)]


def iterate_batches(view, keys, workers: int):
    """(inputs, targets) of each batch: in this process (workers 0) or from a torch DataLoader
    with that many worker processes (each keeps its own cache of signal rates)."""
    if workers == 0:
        for batch in keys:
            yield collate([view[key] for key in batch])
        return
    import torch
    from torch.utils.data import DataLoader
    yield from DataLoader(view, batch_sampler=keys, num_workers=workers, collate_fn=collate,
                          pin_memory=torch.cuda.is_available(), prefetch_factor=4)


def collate(batch):
    """Stack inputs (same size within a batch); keep targets as a list."""
    import torch
    return torch.stack([x for x, _ in batch]), [t for _, t in batch]

"""Training and evaluation of the detectors on data views.

AdamW with a linear warm-up then a cosine decay to zero, over a budget of epochs or of wall-clock
minutes (the schedule then follows elapsed time); checkpoints at every epoch end, written atomically
(temporary file + rename) and read with torch.load(weights_only=True), so a killed run resumes at
its last finished epoch with the same data order and sensor noise. Precision (`autocast_dtype`):
'auto' = bf16 autocast on a CUDA GPU that supports bf16 (Ampere and later), float32 elsewhere;
'bf16' asks for it on any device (on the CPU it runs the same mixed-precision path, which is how
it is tested without a GPU); 'fp32' never. The loss is always computed in float32. bf16 has
float32's exponent range, so no loss scaling is needed; float16 (which would need it) is not used.

A run is one independent job: `run_detection_job(DetectionJob)` is a module-level function of
plain, picklable data that returns a plain result dict, so it runs in-process, in a process pool
or on a cluster through workbench.compute's run_jobs.
"""
from __future__ import annotations

import io
import itertools
import json
import logging
import math
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from workbench.compute.local import THREAD_BUDGET_ENV
from workbench.errors import InputFileError, ParameterError

log = logging.getLogger(__name__)

CHECKPOINT_FORMAT = "camera-workbench-detector-checkpoint"


def choose_threads(requested: int | None = None, concurrent_processes: int = 1) -> int:
    """Torch threads for one process: `requested`, else the thread budget the compute backend gave
    this worker, else half the usable cores shared among concurrent_processes (at least 1), so
    that two CPU-bound processes never oversubscribe."""
    if requested is not None:
        if requested < 1:
            raise ParameterError("threads", requested, "an integer ≥ 1 (or None: half the cores)")
        return int(requested)
    budget = os.environ.get(THREAD_BUDGET_ENV, "")
    if budget.isdigit() and int(budget) > 0:
        return int(budget)
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, cores // (2 * max(1, concurrent_processes)))


def pick_device(device: str) -> str:
    """'cuda' or 'cpu' for 'auto' | 'cuda' | 'cpu' (asking for 'cuda' without a GPU is an error)."""
    import torch
    if device not in ("auto", "cuda", "cpu"):
        raise ParameterError("device", device, "one of 'auto', 'cuda', 'cpu'")
    if device == "cuda" and not torch.cuda.is_available():
        raise ParameterError("device", device, "'cpu' or 'auto': torch sees no CUDA GPU here")
    return "cuda" if device in ("auto", "cuda") and torch.cuda.is_available() else "cpu"


PRECISIONS = ("auto", "fp32", "bf16")


def autocast_dtype(device: str, precision: str):
    """torch.bfloat16 when a run on `device` ('cpu' | 'cuda') should use bf16 autocast, else None."""
    import torch
    if precision not in PRECISIONS:
        raise ParameterError("precision", precision, "one of " + ", ".join(map(repr, PRECISIONS)))
    if precision == "bf16":
        return torch.bfloat16
    if precision == "auto" and device == "cuda" and torch.cuda.is_bf16_supported():
        return torch.bfloat16
    return None


def autocast(device: str, dtype):
    """The autocast context for a run (a no-op one when dtype is None)."""
    import torch
    return torch.autocast(device_type=device, dtype=dtype or torch.bfloat16, enabled=dtype is not None)


@dataclass(frozen=True)
class TrainConfig:
    """One training run. epochs or minutes (exactly one) is the budget; lr is AdamW's peak
    learning rate, reached after warmup_fraction of the budget; crop_hw: training windows (even
    offsets) or None for whole frames; threads None = choose_threads(); init: the name of the run
    whose finished weights start this one ('' = random initialisation; the file is given to
    train_detector)."""

    net: str = "mobile"
    representation: str = "srgb"
    train_evs: tuple[float, ...] = (0.0,)
    seed: int = 0
    epochs: int | None = 10
    minutes: float | None = None
    batch_size: int = 8
    lr: float = 2e-3
    weight_decay: float = 1e-4
    warmup_fraction: float = 0.05
    crop_hw: tuple[int, int] | None = None
    augment: bool = True
    threads: int | None = None
    device: str = "auto"
    precision: str = "auto"
    loader_workers: int = 0
    cache_mb: float = 1024.0
    eval_batch_size: int = 8
    init: str = ""

    def __post_init__(self):
        if (self.epochs is None) == (self.minutes is None):
            raise ParameterError("epochs/minutes", (self.epochs, self.minutes), "exactly one budget: epochs or minutes")
        if self.epochs is not None and self.epochs < 1:
            raise ParameterError("epochs", self.epochs, "an integer ≥ 1")
        if self.minutes is not None and not self.minutes > 0:
            raise ParameterError("minutes", self.minutes, "a number of minutes > 0")
        if self.batch_size < 1:
            raise ParameterError("batch_size", self.batch_size, "an integer ≥ 1")
        if not 0.0 <= self.warmup_fraction < 1.0:
            raise ParameterError("warmup_fraction", self.warmup_fraction, "a fraction in [0, 1)")
        if self.precision not in PRECISIONS:
            raise ParameterError("precision", self.precision, "one of " + ", ".join(map(repr, PRECISIONS)))

    def to_json(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)


def learning_rate(peak: float, progress: float, warmup_fraction: float) -> float:
    """Linear warm-up to `peak` over warmup_fraction, then cosine decay to 0 at progress 1."""
    p = min(max(progress, 0.0), 1.0)
    if warmup_fraction > 0 and p < warmup_fraction:
        return peak * (p / warmup_fraction)
    q = (p - warmup_fraction) / (1.0 - warmup_fraction)
    return peak * 0.5 * (1.0 + math.cos(math.pi * q))


def save_checkpoint(path: str | Path, state: dict) -> None:
    """torch.save the state, then write it whole or not at all (files.atomic_write_bytes)."""
    import torch

    from workbench.files import atomic_write_bytes
    buf = io.BytesIO()
    torch.save({"format": CHECKPOINT_FORMAT, **state}, buf)
    atomic_write_bytes(path, buf.getvalue())


def load_checkpoint(path: str | Path) -> dict | None:
    """The checkpoint at `path` (weights_only=True), or None when there is none."""
    import torch
    path = Path(path)
    if not path.exists():
        return None
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:      # torch raises many types for a damaged or foreign file
        raise InputFileError(path, f"not a readable checkpoint ({exc.__class__.__name__}); delete it to "
                                   "train this run again") from None
    if not isinstance(state, dict) or state.get("format") != CHECKPOINT_FORMAT:
        raise InputFileError(path, "not a workbench detector checkpoint; delete it to train this run again")
    return state


def _encode_batch(targets, num_classes: int, image_hw: tuple[int, int], device: str) -> dict:
    from workbench.detect.centernet import collate_targets, encode_targets
    encoded = [encode_targets(t["boxes_xyxy"].numpy(), t["classes"].numpy(), num_classes, image_hw, stride=4)
               for t in targets]
    return {k: v.to(device) for k, v in collate_targets(encoded).items()}


def _batches(n: int, batch_size: int, rng: np.random.Generator | None, epoch: int = 0):
    """Batches of (item, epoch) keys: a seeded permutation (rng) or the items in order."""
    order = rng.permutation(n) if rng is not None else np.arange(n)
    return [[(int(i), epoch) for i in order[k:k + batch_size]] for k in range(0, n, batch_size)]


def iterate_batches(view, batches, workers: int):
    """(inputs, targets) of each batch: in this process (workers 0) or from a torch DataLoader
    with that many worker processes (each keeps its own cache of signal rates)."""
    from workbench.detect.data import collate
    if workers == 0:
        for batch in batches:
            yield collate([view[key] for key in batch])
        return
    import torch
    from torch.utils.data import DataLoader
    yield from DataLoader(view, batch_sampler=batches, num_workers=workers, collate_fn=collate,
                          pin_memory=torch.cuda.is_available(), prefetch_factor=4)


@dataclass
class TrainResult:
    """What a finished training reports (plain numbers)."""

    epochs: int
    steps: int
    images: int
    seconds: float
    train_ms_per_image: float
    step_ms_per_image: float
    sensor_isp_ms_per_image: float | None
    final_loss: float
    history: list = field(default_factory=list)


def train_detector(dataset, config: TrainConfig, checkpoint_path: str | Path, cancel=None,
                   init_checkpoint: str | Path | None = None):
    """Train config.net on the dataset's training frames; returns (model in eval mode, TrainResult).

    Resumes from checkpoint_path when it holds an unfinished run of the same configuration (a
    checkpoint of another configuration is refused, naming the file). A new run starts from the
    weights of init_checkpoint (a finished run's checkpoint, config.init names it) when given.
    cancel: a CancelToken, checked after every epoch (the checkpoint is written first)."""
    import torch

    from workbench.detect.centernet import centernet_loss
    from workbench.detect.data import DetectionView
    from workbench.detect.models import build_detector
    from workbench.detect.representations import input_channels, input_stride

    torch.set_num_threads(choose_threads(config.threads))
    device = pick_device(config.device)
    view = DetectionView(dataset, dataset.indices("train"), config.representation, config.train_evs,
                         seed=config.seed, augment=config.augment, crop_hw=config.crop_hw, cache_mb=config.cache_mb)
    if len(view) == 0:
        raise ParameterError("data set", str(dataset.folder), "at least one training frame (the split put all in test)")
    in_channels = input_channels(config.representation, view.sensor.cfa_pattern)
    num_classes = len(dataset.class_names)
    torch.manual_seed(config.seed)
    model = build_detector(config.net, in_channels, num_classes,
                           input_stride=input_stride(config.representation)).to(device)
    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    steps_per_epoch = math.ceil(len(view) / config.batch_size)
    budget_s = None if config.minutes is None else 60.0 * config.minutes
    epoch, step, elapsed_s, history, images = 0, 0, 0.0, [], 0
    step_s = 0.0
    state = load_checkpoint(checkpoint_path)
    if state is not None:
        if state.get("config") != config.to_json():
            raise InputFileError(checkpoint_path, "holds a run of another configuration; delete it or choose "
                                                  "another output folder")
        model.load_state_dict(state["model"])
        opt.load_state_dict(state["optimizer"])
        epoch, step, elapsed_s = int(state["epoch"]), int(state["step"]), float(state["elapsed_s"])
        history, images, step_s = list(state["history"]), int(state["images"]), float(state["step_s"])
        log.info("resumed %s at epoch %d from %s", config.net, epoch, checkpoint_path)
    elif config.init:
        base = load_checkpoint(init_checkpoint) if init_checkpoint else None
        if base is None or not base.get("done"):
            raise InputFileError(init_checkpoint or "(none)", f"the finished weights of run '{config.init}' that "
                                                               "this run starts from are missing or unfinished")
        model.load_state_dict(base["model"])
    done = bool(state and state.get("done"))
    amp_dtype = autocast_dtype(device, config.precision)
    model.train()
    def epoch_numbers():
        return itertools.count(epoch) if budget_s is not None else range(epoch, config.epochs)

    keys = (b for e in epoch_numbers()
            for b in _batches(len(view), config.batch_size, np.random.default_rng([config.seed, e, 0x6F7264]), e))
    stream = iterate_batches(view, keys, config.loader_workers)
    sensor_isp_s, sensor_items = 0.0, 0
    for e in ([] if done else epoch_numbers()):
        t_epoch, losses = time.perf_counter(), []
        t0 = time.perf_counter()
        for _ in range(steps_per_epoch):
            progress = step / (config.epochs * steps_per_epoch) if budget_s is None else elapsed_s / budget_s
            for group in opt.param_groups:
                group["lr"] = learning_rate(config.lr, progress, config.warmup_fraction)
            x, targets = next(stream)
            t1 = time.perf_counter()
            sensor_isp_s += sum(t["sensor_isp_s"] for t in targets)
            sensor_items += len(targets)
            hw = tuple(x.shape[-2:]) if config.representation != "raw" else (x.shape[-2] * 2, x.shape[-1] * 2)
            enc = _encode_batch(targets, num_classes, hw, device)
            x = x.to(device, non_blocking=True)
            with autocast(device, amp_dtype):
                out = model(x)
            loss, _ = centernet_loss({k: v.float() for k, v in out.items()}, enc)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), 10.0)
            opt.step()
            if device == "cuda":
                torch.cuda.synchronize()
            t2 = time.perf_counter()
            step_s += t2 - t1
            elapsed_s += t2 - t0
            t0 = t2
            step += 1
            images += len(targets)
            losses.append(float(loss.detach()))
            if budget_s is not None and elapsed_s >= budget_s:
                break
        epoch = e + 1
        history.append({"epoch": epoch, "loss": float(np.mean(losses)), "seconds": time.perf_counter() - t_epoch})
        done = (epoch >= config.epochs) if budget_s is None else elapsed_s >= budget_s
        log.info("%s %s EV%s seed %d: epoch %d loss %.3f (%.0f img/s)", config.net, config.representation,
                 ",".join(f"{e:+g}" for e in config.train_evs), config.seed, epoch, history[-1]["loss"],
                 len(losses) * config.batch_size / max(history[-1]["seconds"], 1e-9))
        save_checkpoint(checkpoint_path, {"config": config.to_json(), "model": model.state_dict(),
                                          "optimizer": opt.state_dict(), "epoch": epoch, "step": step,
                                          "elapsed_s": elapsed_s, "history": history, "images": images,
                                          "step_s": step_s, "done": done})
        if done:
            break
        if cancel is not None:
            cancel.check()
    model.eval()
    sensor_ms = 1e3 * sensor_isp_s / sensor_items if sensor_items else None
    return model, TrainResult(epochs=epoch, steps=step, images=images, seconds=elapsed_s,
                              train_ms_per_image=1e3 * elapsed_s / max(images, 1),
                              step_ms_per_image=1e3 * step_s / max(images, 1),
                              sensor_isp_ms_per_image=sensor_ms,
                              final_loss=history[-1]["loss"] if history else float("nan"), history=history)


def evaluate_detector(model, view, class_names, *, device: str = "cpu", batch_size: int = 8,
                      with_curves: bool = False, workers: int = 0, precision: str = "auto") -> dict:
    """VOC all-point AP@0.5 per class and mAP on a view (ignored boxes handled as in
    workbench.detect.data; None where no class has ground truth; inference under autocast_dtype(
    device, precision), decoding in float32), pycocotools' AP@0.5 as a
    cross-check (None without pycocotools), inference and sensor + ISP ms per image, and with
    with_curves each class's precision–recall curve (at most 50 points)."""
    import torch

    from workbench.detect.centernet import decode
    from workbench.detect.data import drop_ignored_detections
    from workbench.detect.evaluate import evaluate_map, pycocotools_ap50

    detections, truths = [], []
    infer_s, sensor_isp_s = 0.0, 0.0
    amp_dtype = autocast_dtype(device, precision)
    with torch.no_grad():
        for x, targets in iterate_batches(view, _batches(len(view), batch_size, None), workers):
            sensor_isp_s += sum(t["sensor_isp_s"] for t in targets)
            t0 = time.perf_counter()
            with autocast(device, amp_dtype):
                out = model(x.to(device))
            dets = decode({k: v.float() for k, v in out.items()}, stride=4, k=100, score_threshold=0.01)
            if device == "cuda":
                torch.cuda.synchronize()
            infer_s += time.perf_counter() - t0
            for det, tgt in zip(dets, targets):
                boxes, scores, classes = drop_ignored_detections(
                    det["boxes"], det["scores"], det["classes"], tgt["boxes_xyxy"].numpy(), tgt["classes"].numpy(),
                    tgt["ignored_xyxy"].numpy(), tgt["ignored_classes"].numpy())
                detections.append({"boxes": boxes, "scores": scores, "classes": classes})
                truths.append({"boxes": tgt["boxes_xyxy"].numpy(), "classes": tgt["classes"].numpy()})
    voc = evaluate_map(detections, truths, list(class_names), iou=0.5).to_dict()
    out = {"map": voc["mean_ap"], "ap": voc["ap"], "n_ground_truth": voc["n_ground_truth"],
           "images": len(view), "infer_ms_per_image": 1e3 * infer_s / max(len(view), 1),
           "sensor_isp_ms_per_image": 1e3 * sensor_isp_s / max(len(view), 1)}
    try:
        coco = pycocotools_ap50(detections, truths, list(class_names))["mean_ap"]
        out["coco_ap50"] = None if math.isnan(coco) else coco
    except ImportError:                      # pycocotools absent (a bare GPU machine): no cross-check
        out["coco_ap50"] = None
    if with_curves:
        out["curves"] = {name: {k: _thin(v) for k, v in curve.items()} for name, curve in voc["curves"].items()}
    return out


def _thin(values: list, points: int = 50) -> list:
    """At most `points` evenly spaced entries of a precision or recall list (keeps the last)."""
    if len(values) <= points:
        return values
    return [values[int(i)] for i in np.linspace(0, len(values) - 1, points).round()]


@dataclass(frozen=True)
class DetectionJob:
    """One run as plain data: train `config` on the data set, then test on its test frames at
    each of test_evs (the training representation; none for a run that only makes starting
    weights). checkpoint: the run's checkpoint file; init_checkpoint: the file of config.init."""

    key: str
    dataset_dir: str
    config: TrainConfig
    test_evs: tuple[float, ...]
    checkpoint: str
    with_curves: bool = False
    init_checkpoint: str | None = None

    def __repr__(self) -> str:
        return f"DetectionJob({self.key})"


def run_detection_job(job: DetectionJob, cancel=None) -> dict:
    """Train (or resume) and test one run; return a plain dict: key, config, train figures and one
    entry per test EV (mAP, AP per class, COCO AP@0.5, inference ms per image)."""
    from workbench.detect.data import DetectionDataset, DetectionView

    dataset = DetectionDataset(job.dataset_dir)
    model, tr = train_detector(dataset, job.config, job.checkpoint, cancel, job.init_checkpoint)
    device = pick_device(job.config.device)
    tests = []
    for ev in job.test_evs:
        view = DetectionView(dataset, dataset.indices("test"), job.config.representation, (ev,),
                             cache_mb=job.config.cache_mb)
        t0 = time.perf_counter()
        res = evaluate_detector(model, view, dataset.class_names, device=device,
                                batch_size=job.config.eval_batch_size, with_curves=job.with_curves,
                                workers=job.config.loader_workers, precision=job.config.precision)
        res.update({"ev": float(ev), "seconds": time.perf_counter() - t0})
        tests.append(res)
    train = asdict(tr)
    return {"key": job.key, "config": json.loads(job.config.to_json()), "train": train, "tests": tests,
            "classes": list(dataset.class_names), "device": device}

"""Training a detector on a data view: the loop, its schedule, and the record that says whether
it converged.

AdamW with a linear warm-up, then a cosine decay to zero over a fixed number of epochs (one
epoch = every training frame once, as a crop_hw window when given). A run records its loss
curve (the total and the three CenterNet parts, per epoch) and a train-mAP curve: mAP@0.5 of the
network on a fixed subset of its own training frames (whole frames, no augmentation, at the
middle training EV) at `curve_points` evenly spaced epochs, always including the one at half the
budget. `convergence` reads that curve: a run is converged when its train mAP at the end is at
least CONVERGED_FLOOR (it learned something) and gained less than CONVERGED_GAIN over the second
half of the budget (more training would not have helped); it says which test failed, and is None
when the curve has no end and half-way points.

Checkpoints at every epoch end, written atomically and read weights-only, so a killed run
resumes at its last finished epoch with the same data order and sensor noise (cancel is checked
after each epoch, once the checkpoint is written). A run resumed on another machine records each
process's part (`segments`: the CPU or GPU, its epochs and training seconds): CPUs differ 2–4×
in training speed, so a run's ms per image means something only with the machines beside it.
"""
from __future__ import annotations

import itertools
import json
import logging
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from workbench.detect.checkpoint import check_training_state, load_checkpoint, save_checkpoint
from workbench.detect.devices import PRECISIONS, autocast, autocast_dtype, choose_threads, pick_device
from workbench.detect.devices import compute_unit, prepare_input, prepare_model
from workbench.errors import InputFileError, ParameterError, StageError

log = logging.getLogger(__name__)

ORDER_TAG = 0x6F7264              # 'ord': the batch order's stream
CONVERGED_GAIN = 0.03             # train-mAP gain over the second half below which a run has stopped climbing
CONVERGED_FLOOR = 0.2             # end train mAP below which a flat curve is stuck, not converged: an
                                  # untrained net reads ≈ 0 (6-epoch quick runs: 0.000), one that fits its
                                  # own frames ≥ 0.8 (the learnable synthetic set; 0.948 after 60 epochs);
                                  # below a fifth of that it has not fit the frames it trains on


@dataclass(frozen=True)
class TrainConfig:
    """One training run. epochs: the budget (every training frame once per epoch); lr: AdamW's
    peak learning rate, reached after warmup_fraction of the budget; crop_hw: training windows
    (even offsets) or None for whole frames; threads None = choose_threads(); curve_points /
    curve_frames: how often, and on how many training frames, the train-mAP curve is measured."""

    net: str = "mobile"
    representation: str = "srgb"
    train_evs: tuple[float, ...] = (0.0,)
    seed: int = 0
    epochs: int = 10
    batch_size: int = 16
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
    eval_batch_size: int = 16
    curve_points: int = 6
    curve_frames: int = 48

    def __post_init__(self):
        for name, low in (("epochs", 1), ("batch_size", 1), ("eval_batch_size", 1), ("curve_points", 0),
                          ("curve_frames", 1), ("loader_workers", 0)):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < low:
                raise ParameterError(name, value, f"an integer ≥ {low}")
        if not (self.lr > 0 and math.isfinite(self.lr)):
            raise ParameterError("lr", self.lr, "a finite learning rate > 0")
        if not 0.0 <= self.warmup_fraction < 1.0:
            raise ParameterError("warmup_fraction", self.warmup_fraction, "a fraction in [0, 1)")
        if self.precision not in PRECISIONS:
            raise ParameterError("precision", self.precision, "one of " + ", ".join(map(repr, PRECISIONS)))
        if not self.train_evs:
            raise ParameterError("train_evs", self.train_evs, "one or more EV biases")

    def to_json(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)

    @property
    def curve_ev(self) -> float:
        """The EV at which the train-mAP curve is measured: the middle of the training EVs."""
        return float(sorted(self.train_evs)[len(self.train_evs) // 2])


def learning_rate(peak: float, progress: float, warmup_fraction: float) -> float:
    """Linear warm-up to `peak` over warmup_fraction, then cosine decay to 0 at progress 1."""
    p = min(max(progress, 0.0), 1.0)
    if warmup_fraction > 0 and p < warmup_fraction:
        return peak * (p / warmup_fraction)
    q = (p - warmup_fraction) / (1.0 - warmup_fraction)
    return peak * 0.5 * (1.0 + math.cos(math.pi * q))


def curve_epochs(epochs: int, points: int) -> list[int]:
    """The epochs (1-based, ascending, the last one included) after which the train-mAP curve is
    measured: `points` of them, evenly spaced, plus the half-way epoch (epochs // 2, the last at
    or before half the budget) when points ≥ 2 and it is not among them."""
    if points == 0:
        return []
    chosen = {max(1, round(epochs * (k + 1) / points)) for k in range(points)}
    if points >= 2 and epochs >= 2:
        chosen.add(epochs // 2)
    return sorted(chosen)


def convergence(curve: list[dict], epochs: int) -> dict:
    """train_map_half (the last curve point at or before epochs / 2), train_map_end (the point at
    the last epoch), half_gain (end − half), converged and the reason in words; the numbers and
    converged are None when the curve has no such pair."""
    half = [c for c in curve if c["epoch"] <= epochs / 2 and c["train_map"] is not None]
    end = curve[-1] if curve and curve[-1]["epoch"] == epochs and curve[-1]["train_map"] is not None else None
    if not half or end is None:
        return {"train_map_half": None, "train_map_end": None, "half_gain": None, "converged": None,
                "convergence": "unknown: no train mAP at half the budget and at its end"}
    at_half, at_end = float(half[-1]["train_map"]), float(end["train_map"])
    gain = at_end - at_half
    if at_end < CONVERGED_FLOOR:
        verdict, why = False, f"stuck: train mAP {at_end:.3f} < floor {CONVERGED_FLOOR:g}"
    elif gain >= CONVERGED_GAIN:
        verdict, why = False, f"still climbing: {gain:+.3f} after half the budget"
    else:
        verdict, why = True, f"converged: {gain:+.3f} after half the budget"
    return {"train_map_half": at_half, "train_map_end": at_end, "half_gain": gain, "converged": verdict,
            "convergence": why}


NOT_RECORDED = "not recorded"      # the machine of epochs a checkpoint from before segments holds


def training_segments(state: dict | None) -> list[dict]:
    """The parts of a run its checkpoint says were trained, one per process: {"unit": CPU or GPU
    in words, "first_epoch", "last_epoch", "seconds"}. A checkpoint written before segments were
    recorded (or with a damaged list) gives its epochs as one part of an unknown machine."""
    if not state or not state.get("epoch"):
        return []
    kept = state.get("segments")
    ok = isinstance(kept, list) and all(
        isinstance(g, dict) and isinstance(g.get("unit"), str) and isinstance(g.get("first_epoch"), int)
        and isinstance(g.get("last_epoch"), int) and isinstance(g.get("seconds"), (int, float)) for g in kept)
    if ok and kept and kept[-1]["last_epoch"] == state["epoch"]:
        return [dict(g) for g in kept]
    return [{"unit": NOT_RECORDED, "first_epoch": 1, "last_epoch": int(state["epoch"]),
             "seconds": float(state.get("elapsed_s", 0.0))}]


def _encode_batch(targets, num_classes: int, image_hw: tuple[int, int], device: str) -> dict:
    from workbench.detect.centernet import collate_targets, encode_targets
    encoded = [encode_targets(t["boxes_xyxy"].numpy(), t["classes"].numpy(), num_classes, image_hw, stride=4,
                              ignored_xyxy=t["ignored_xyxy"].numpy(), ignored_classes=t["ignored_classes"].numpy())
               for t in targets]
    return {k: v.to(device) for k, v in collate_targets(encoded).items()}


@dataclass
class TrainResult:
    """What a finished training reports (plain numbers): budget used, speed (ms per training
    image: all of it, the network step alone, sensor + ISP alone), the loss curve (history, one
    entry per epoch) and the train-mAP curve with its reading (engine.convergence)."""

    epochs: int
    steps: int
    images: int
    seconds: float
    train_ms_per_image: float
    step_ms_per_image: float
    sensor_isp_ms_per_image: float | None
    final_loss: float
    history: list = field(default_factory=list)
    curve: list = field(default_factory=list)
    train_map_half: float | None = None
    train_map_end: float | None = None
    half_gain: float | None = None
    converged: bool | None = None
    convergence: str = ""
    autocast: str = "fp32"                 # what the run computed in: 'bf16' (autocast) or 'fp32'
    segments: list = field(default_factory=list)   # training_segments: who trained which epochs


def train_view(dataset, config: TrainConfig):
    """The training view of a config: the training frames, its representation and EVs, seeded
    augmentation and crops."""
    from workbench.detect.data import DetectionView
    view = DetectionView(dataset, dataset.indices("train"), config.representation, config.train_evs,
                         seed=config.seed, augment=config.augment, crop_hw=config.crop_hw, cache_mb=config.cache_mb)
    if len(view) == 0:
        raise ParameterError("data set", str(dataset.folder), "at least one training frame (the split put all in test)")
    return view


def curve_view(dataset, config: TrainConfig):
    """The fixed training frames (whole, unaugmented, at config.curve_ev) the train-mAP curve uses."""
    from workbench.detect.data import DetectionView
    train = dataset.indices("train")
    step = max(1, len(train) // config.curve_frames)
    return DetectionView(dataset, train[::step][:config.curve_frames], config.representation, (config.curve_ev,),
                         cache_mb=config.cache_mb)


def train_detector(dataset, config: TrainConfig, checkpoint_path: str | Path, cancel=None):
    """Train config.net on the dataset's training frames; returns (model in eval mode, TrainResult).

    Resumes from checkpoint_path when it holds an unfinished run of the same configuration (a
    checkpoint of another configuration is refused, naming the file); a finished one is loaded,
    not retrained. cancel: a CancelToken, checked after every epoch (the checkpoint is written first)."""
    import torch

    from workbench.detect.centernet import centernet_loss
    from workbench.detect.data import batches, iterate_batches
    from workbench.detect.inference import evaluate_detector
    from workbench.detect.models import build_detector
    from workbench.detect.representations import input_channels, input_stride

    torch.set_num_threads(choose_threads(config.threads))
    device = pick_device(config.device)
    view = train_view(dataset, config)
    in_channels = input_channels(config.representation, view.sensor.cfa_pattern)
    num_classes = len(dataset.class_names)
    torch.manual_seed(config.seed)
    model = prepare_model(build_detector(config.net, in_channels, num_classes,
                                         input_stride=input_stride(config.representation)), device)
    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    steps_per_epoch = math.ceil(len(view) / config.batch_size)
    total_steps = config.epochs * steps_per_epoch
    epoch, step, elapsed_s, history, curve, images, step_s = 0, 0, 0.0, [], [], 0, 0.0
    state = load_checkpoint(checkpoint_path)
    if state is not None:
        if state.get("config") != config.to_json():
            raise InputFileError(checkpoint_path, "holds a run of another configuration; delete it or choose "
                                                  "another output folder")
        check_training_state(checkpoint_path, state, config.epochs)
        try:
            model.load_state_dict(state["model"])
            opt.load_state_dict(state["optimizer"])
        except (RuntimeError, KeyError, ValueError, TypeError, IndexError) as exc:   # torch's shape and key checks
            raise InputFileError(checkpoint_path, f"its weights do not fit this network ({exc.__class__.__name__});"
                                                  " delete it to train this run again") from None
        epoch, step, elapsed_s = int(state["epoch"]), int(state["step"]), float(state["elapsed_s"])
        history, curve, images = list(state["history"]), list(state["curve"]), int(state["images"])
        if step != epoch * steps_per_epoch or images != epoch * len(view):
            raise InputFileError(checkpoint_path, f"its counters ({step} steps, {images} images) are not those of "
                                                  f"{epoch} epochs on this data set; delete it to train this run again")
        step_s = float(state["step_s"])
        log.info("resumed %s at epoch %d from %s", config.net, epoch, checkpoint_path)
    done = bool(state and state.get("done"))
    segments, mine, elapsed_before = training_segments(state), None, elapsed_s
    amp_dtype = autocast_dtype(device, config.precision)
    at_curve = set(curve_epochs(config.epochs, config.curve_points))
    keys = (b for e in itertools.count(epoch)
            for b in batches(len(view), config.batch_size, np.random.default_rng([config.seed, e, ORDER_TAG]), e))
    stream = iterate_batches(view, keys, config.loader_workers)
    sensor_isp_s, sensor_items = 0.0, 0
    for e in ([] if done else range(epoch, config.epochs)):
        model.train()
        t_epoch, parts = time.perf_counter(), []
        t0 = time.perf_counter()
        for _ in range(steps_per_epoch):
            for group in opt.param_groups:
                group["lr"] = learning_rate(config.lr, step / total_steps, config.warmup_fraction)
            x, targets = next(stream)
            t1 = time.perf_counter()
            sensor_isp_s += sum(t["sensor_isp_s"] for t in targets)
            sensor_items += len(targets)
            hw = tuple(x.shape[-2:]) if config.representation != "raw" else (x.shape[-2] * 2, x.shape[-1] * 2)
            enc = _encode_batch(targets, num_classes, hw, device)
            with autocast(device, amp_dtype):
                out = model(prepare_input(x, device))
            loss, part = centernet_loss({k: v.float() for k, v in out.items()}, enc)
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
            parts.append([float(loss.detach())] + [float(part[k]) for k in ("heatmap", "size", "offset")])
        epoch = e + 1
        mean = np.mean(parts, axis=0)
        if not np.all(np.isfinite(mean)):          # diverged: no checkpoint, no record of NaN weights
            raise StageError("training", f"{config.net} {config.representation} seed {config.seed}: the loss is "
                                         f"{mean[0]} at epoch {epoch}; the run diverged (lower lr, now {config.lr:g})")
        history.append({"epoch": epoch, "loss": float(mean[0]), "heatmap": float(mean[1]), "size": float(mean[2]),
                        "offset": float(mean[3]), "seconds": time.perf_counter() - t_epoch})
        if epoch in at_curve:
            model.eval()
            res = evaluate_detector(model, curve_view(dataset, config), dataset.class_names, device=device,
                                    batch_size=config.eval_batch_size, precision=config.precision)
            curve.append({"epoch": epoch, "images": images, "train_map": res["map"]})
        if mine is None:
            mine = {"unit": compute_unit(device), "first_epoch": epoch, "last_epoch": epoch, "seconds": 0.0}
            segments.append(mine)
        mine.update(last_epoch=epoch, seconds=elapsed_s - elapsed_before)
        done = epoch >= config.epochs
        log.info("%s %s EV%s seed %d: epoch %d loss %.3f%s", config.net, config.representation,
                 ",".join(f"{v:+g}" for v in config.train_evs), config.seed, epoch, history[-1]["loss"],
                 f", train mAP {curve[-1]['train_map']:.3f}" if curve and curve[-1]["epoch"] == epoch
                 and curve[-1]["train_map"] is not None else "")
        save_checkpoint(checkpoint_path, {"config": config.to_json(), "model": model.state_dict(),
                                          "optimizer": opt.state_dict(), "epoch": epoch, "step": step,
                                          "elapsed_s": elapsed_s, "history": history, "curve": curve,
                                          "images": images, "step_s": step_s, "done": done,
                                          "segments": segments})
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
                              final_loss=history[-1]["loss"] if history else float("nan"), history=history,
                              curve=curve, **convergence(curve, config.epochs),
                              autocast="bf16" if amp_dtype is not None else "fp32", segments=segments)

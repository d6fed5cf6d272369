"""How well a trained detector finds road users through a camera design: test mAP@0.5 of a
checkpoint on a rendered data set, with the design's sensor and ISP run on the fly (as in the
experiments). Only fields that leave the rendered frames as they are may differ from the data
set's project (sensor noise, gains, exposure, ISP); DetectionDataset refuses the rest by name."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from workbench.errors import InputFileError


def read_trained(checkpoint_path: str | Path):
    """(state, TrainConfig) of a finished checkpoint; a missing, unfinished or unreadable one is an
    InputFileError naming the file."""
    from workbench.detect.checkpoint import check_training_state, load_checkpoint
    from workbench.detect.engine import TrainConfig

    path = Path(checkpoint_path)
    state = load_checkpoint(path)
    if state is None:
        raise InputFileError(path, "no such checkpoint; give one written by `workbench experiment` or training")
    if not state.get("done"):
        raise InputFileError(path, "holds an unfinished training run; finish it (rerun its experiment) first")
    try:
        fields = json.loads(state["config"])
        for name in ("train_evs", "crop_hw"):
            if isinstance(fields.get(name), list):
                fields[name] = tuple(fields[name])
        config = TrainConfig(**fields)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputFileError(path, f"its training configuration is unreadable ({type(exc).__name__})") from None
    check_training_state(path, state, config.epochs)        # "done" with the history and finite weights of done
    return state, config


def trained_model(checkpoint_path: str | Path, state: dict, config, in_channels: int, num_classes: int):
    """The checkpoint's net in eval mode on the CPU; a net trained for another input or class list
    is an InputFileError."""
    from workbench.detect.devices import prepare_model
    from workbench.detect.models import build_detector
    from workbench.detect.representations import input_stride

    if not isinstance(state.get("model"), dict):
        raise InputFileError(Path(checkpoint_path), "holds no trained weights (no 'model' entry); give a checkpoint "
                             "that `workbench experiment` or training wrote")
    model = build_detector(config.net, in_channels, num_classes, input_stride=input_stride(config.representation))
    try:
        model.load_state_dict(state["model"])
    except RuntimeError:
        raise InputFileError(Path(checkpoint_path), f"its {config.net} net was trained for another input "
                             f"({config.representation}) or class list than this design's {in_channels} "
                             f"channels and {num_classes} classes") from None
    return prepare_model(model, "cpu").eval()


def design_map(project, checkpoint_path: str | Path, data_dir: str | Path, *, bootstrap: int = 0) -> dict:
    """Test mAP@0.5 (and AP per class) of the checkpoint's detector on the data set's test frames
    at EV 0, seen through `project`'s sensor and ISP; with bootstrap > 0 test-set resamples, the
    standard deviation of their mAP ('map_bootstrap_sd', else None)."""
    import torch

    from workbench.detect.data import DetectionDataset, DetectionView
    from workbench.detect.devices import choose_threads
    from workbench.detect.inference import evaluate_detector
    from workbench.detect.representations import input_channels

    torch.set_num_threads(choose_threads())
    dataset = DetectionDataset(data_dir, project=project)
    test = dataset.test_indices()
    state, config = read_trained(checkpoint_path)
    view = DetectionView(dataset, test, config.representation, (0.0,))
    model = trained_model(checkpoint_path, state, config, input_channels(config.representation, view.sensor.cfa_pattern),
                          len(dataset.class_names))
    res = evaluate_detector(model, view, dataset.class_names, precision=config.precision, bootstrap=bootstrap)
    maps = [m for m in res.get("bootstrap_map", []) if m is not None]
    return {"map": res["map"], "ap": res["ap"], "test_images": res["images"], "net": config.net,
            "representation": config.representation,
            "map_bootstrap_sd": float(np.std(maps, ddof=1)) if len(maps) > 1 else None}

"""A checkpoint is trusted only if it is what training wrote: one edited to "done" before its
budget, with a history that does not match its epoch, or with NaN/Inf weights is refused naming
the file (issue 34), never taken as a finished run with a NaN in its results."""
import math

import pytest
import torch

from workbench.detect.checkpoint import load_checkpoint, save_checkpoint
from workbench.detect.data import DetectionDataset
from workbench.detect.engine import TrainConfig, train_detector
from workbench.errors import InputFileError, StageError

TINY = dict(net="mobile", representation="srgb", epochs=2, batch_size=4, threads=1, device="cpu", curve_points=2,
            curve_frames=4)


@pytest.fixture(scope="module")
def finished(synthetic_dir, tmp_path_factory):
    """A finished 2-epoch run's checkpoint state (trained once for the module)."""
    torch.set_num_threads(1)
    path = tmp_path_factory.mktemp("ckpt") / "run.pt"
    train_detector(DetectionDataset(synthetic_dir), TrainConfig(**TINY), path)
    return load_checkpoint(path)


def _nan_weights(state):
    model = {k: v.clone() for k, v in state["model"].items()}
    first = next(k for k, v in model.items() if v.is_floating_point())
    model[first][...] = math.nan
    return {**state, "model": model}


@pytest.mark.parametrize("edit, fragment", [
    (lambda s: {**s, "epoch": 0, "history": [], "curve": []}, "done=True at epoch 0 of 2"),
    (lambda s: {**s, "history": s["history"][:1]}, "1 entries for 2 epochs"),
    (lambda s: {**s, "done": False}, "done=False at epoch 2 of 2"),
    (lambda s: {**s, "epoch": 7}, "epoch 7"),
    (lambda s: {**s, "history": [{**h, "loss": math.nan} for h in s["history"]]}, "finite loss"),
    (lambda s: {**s, "curve": [{"epoch": 2, "train_map": 2.5}]}, "train-mAP curve"),
    (_nan_weights, "weights hold NaN or Inf"),
    (lambda s: {**s, "model": {"w": torch.ones(2)}}, "do not fit this network"),
])
def test_a_checkpoint_training_did_not_write_is_refused_naming_it(synthetic_dir, tmp_path, finished, edit, fragment):
    path = tmp_path / "run.pt"
    save_checkpoint(path, {k: v for k, v in edit(finished).items() if k != "format"})
    with pytest.raises(InputFileError, match=fragment) as info:
        train_detector(DetectionDataset(synthetic_dir), TrainConfig(**TINY), path)
    assert str(path) in str(info.value) and "delete it" in str(info.value)


def test_the_finished_checkpoint_itself_is_loaded_not_retrained(synthetic_dir, tmp_path, finished):
    path = tmp_path / "run.pt"
    save_checkpoint(path, {k: v for k, v in finished.items() if k != "format"})
    _, result = train_detector(DetectionDataset(synthetic_dir), TrainConfig(**TINY), path)
    assert result.epochs == 2 and len(result.history) == 2 and math.isfinite(result.final_loss)


def test_a_diverging_run_stops_without_a_checkpoint(synthetic_dir, tmp_path, monkeypatch):
    from workbench.detect import centernet
    real = centernet.centernet_loss

    def nan_loss(out, enc):
        loss, parts = real(out, enc)
        return loss * math.nan, parts
    monkeypatch.setattr(centernet, "centernet_loss", nan_loss)
    with pytest.raises(StageError, match="diverged"):
        train_detector(DetectionDataset(synthetic_dir), TrainConfig(**TINY), tmp_path / "run.pt")
    assert not (tmp_path / "run.pt").exists()


def test_a_checkpoint_changed_after_training_wrote_it_is_refused(synthetic_dir, tmp_path, finished):
    path = tmp_path / "run.pt"
    for edit in ({"elapsed_s": finished["elapsed_s"] + 1}, {"curve": [{**finished["curve"][-1], "train_map": 0.99}]},
                 {"step": finished["step"] + 1}):
        torch.save({**finished, **edit}, path)               # the old checksum kept
        with pytest.raises(InputFileError, match="run.pt") as info:
            train_detector(DetectionDataset(synthetic_dir), TrainConfig(**TINY), path)
        assert "checksum" in str(info.value) or "counters" in str(info.value)


def test_a_checkpoint_without_a_checksum_still_resumes(synthetic_dir, tmp_path, finished):
    path = tmp_path / "run.pt"
    torch.save({k: v for k, v in finished.items() if k != "checksum"}, path)    # written before checksums
    _, result = train_detector(DetectionDataset(synthetic_dir), TrainConfig(**TINY), path)
    assert result.epochs == 2


def test_a_study_detector_checkpoint_with_nan_weights_is_refused(tmp_path, finished):
    from workbench.metrics.detection import read_trained
    path = tmp_path / "run.pt"
    save_checkpoint(path, {k: v for k, v in _nan_weights(finished).items() if k != "format"})
    with pytest.raises(InputFileError, match="NaN"):
        read_trained(path)

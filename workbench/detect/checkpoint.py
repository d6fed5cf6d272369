"""Detector checkpoints: written whole or not at all, read without unpickling code.

A checkpoint is a dict saved with torch.save under a format tag; it is read with
torch.load(weights_only=True), so a checkpoint file (untrusted input) cannot run code, and
`check_training_state` refuses one that is not what training wrote: a history that does not
match its epoch or its "done", weights and optimizer moments that hold NaN or Inf, or (for one
written with a checksum: all since issue 34) any change to what training reads from it.
"""
from __future__ import annotations

import io
import math
from pathlib import Path

from workbench.errors import InputFileError

CHECKPOINT_FORMAT = "camera-workbench-detector-checkpoint"


# the entries of a training state its checksum covers (what a resumed or finished run reads)
CHECKED_FIELDS = ("config", "model", "optimizer", "epoch", "step", "elapsed_s", "history", "curve", "images",
                  "step_s", "done")


def _feed(h, node) -> None:
    """Add a (nested) state to the hash h: tensors by dtype, shape and bytes, the rest as JSON."""
    import torch
    if isinstance(node, torch.Tensor):
        t = node.detach().cpu().contiguous().reshape(-1)
        h.update(f"T{t.dtype}{tuple(node.shape)}".encode())
        h.update(t.view(torch.uint8).numpy().tobytes())
    elif isinstance(node, dict):
        h.update(b"{")
        for key in sorted(node, key=repr):
            h.update(repr(key).encode())
            _feed(h, node[key])
        h.update(b"}")
    elif isinstance(node, (list, tuple)):
        h.update(b"[")
        for item in node:
            _feed(h, item)
        h.update(b"]")
    else:
        h.update(repr((type(node).__name__, node)).encode())


def state_checksum(state: dict) -> str:
    """SHA-256 (hex) of the CHECKED_FIELDS of a training state, weights included."""
    import hashlib
    h = hashlib.sha256()
    _feed(h, {k: state.get(k) for k in CHECKED_FIELDS})
    return h.hexdigest()


def save_checkpoint(path: str | Path, state: dict) -> None:
    """torch.save the state with its checksum, then write it whole or not at all
    (files.atomic_write_bytes)."""
    import torch

    from workbench.files import atomic_write_bytes
    buf = io.BytesIO()
    torch.save({"format": CHECKPOINT_FORMAT, **state, "checksum": state_checksum(state)}, buf)
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


def _finite_tensors(node) -> bool:
    """Whether every tensor in a (nested) state dict is finite."""
    import torch
    if isinstance(node, torch.Tensor):
        return not node.is_floating_point() or bool(torch.isfinite(node).all())
    if isinstance(node, dict):
        return all(_finite_tensors(v) for v in node.values())
    if isinstance(node, (list, tuple)):
        return all(_finite_tensors(v) for v in node)
    return True


def _is_int(value, low: int, high: int | None = None) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= low and (high is None or value <= high)


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _history_problem(state: dict, epochs: int) -> str | None:
    """What is inconsistent in a training state of a run of `epochs` epochs, or None."""
    epoch, history, curve = state.get("epoch"), state.get("history"), state.get("curve")
    if not _is_int(epoch, 0, epochs):
        return f"epoch {epoch!r} is not an epoch of this run (0…{epochs})"
    if not (_is_int(state.get("step"), 0) and _is_int(state.get("images"), 0)
            and _is_number(state.get("elapsed_s")) and _is_number(state.get("step_s"))):
        return "its step, image or time counters are not counts"
    if not isinstance(history, list) or len(history) != epoch:
        entries = len(history) if isinstance(history, list) else "no"
        return f"its loss history holds {entries} entries for {epoch} epochs"
    for k, entry in enumerate(history, 1):
        if not (isinstance(entry, dict) and entry.get("epoch") == k and _is_number(entry.get("loss")) and all(
                _is_number(v) and v >= 0 for name, v in entry.items() if name != "epoch")):
            return f"its loss history entry {k} is not epoch {k} with finite losses ≥ 0"
    if not isinstance(curve, list) or not all(
            isinstance(c, dict) and _is_int(c.get("epoch"), 1, epoch) and
            (c.get("train_map") is None or _is_number(c["train_map"]) and 0.0 <= c["train_map"] <= 1.0)
            for c in curve):
        return "its train-mAP curve is not a list of epochs of this run with mAPs in 0…1"
    if state.get("done") is not (epoch == epochs):
        return f"it says done={state.get('done')!r} at epoch {epoch} of {epochs}"
    return None


def check_training_state(path: str | Path, state: dict, epochs: int) -> None:
    """InputFileError naming the checkpoint when it is not a state training of `epochs` epochs
    wrote: counters, loss history and train-mAP curve consistent with its epoch and "done", every
    weight and optimizer moment finite. Refused, not retrained: the same seed would train the
    same run, so a damaged file is something to look at, and deleting it retrains it."""
    problem = _history_problem(state, epochs)
    if problem is None and not (isinstance(state.get("model"), dict) and isinstance(state.get("optimizer"), dict)):
        problem = "it holds no model or optimizer state"
    if problem is None and not _finite_tensors(state["model"]):
        problem = "its weights hold NaN or Inf"
    if problem is None and not _finite_tensors(state["optimizer"]):
        problem = "its optimizer state holds NaN or Inf"
    if problem is None and "checksum" in state and state["checksum"] != state_checksum(state):
        problem = "it was changed after training wrote it (its checksum does not match)"
    if problem is not None:
        raise InputFileError(path, f"not a checkpoint training wrote: {problem}; delete it to train this run again")

"""Detector checkpoints: written whole or not at all, read without unpickling code.

A checkpoint is a dict saved with torch.save under a format tag; it is read with
torch.load(weights_only=True), so a checkpoint file (untrusted input) cannot run code.
"""
from __future__ import annotations

import io
from pathlib import Path

from workbench.errors import InputFileError

CHECKPOINT_FORMAT = "camera-workbench-detector-checkpoint"


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

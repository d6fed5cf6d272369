"""Edits of a data set's files for tests that check they are refused: a JSON file changed in
place, a frame file rewritten as a valid .npz with other content."""
from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np


def edit_json(folder: Path, name: str, change) -> Path:
    """Apply change(doc) to the JSON file folder/name and write it back; returns its path."""
    path = folder / name
    doc = json.loads(path.read_text())
    change(doc)
    path.write_text(json.dumps(doc))
    return path


def rewrite_frame(path: Path, change, data: bytes | None = None) -> None:
    """Rewrite a frame file (its bytes `data`, else read from path) with change(arrays, header)
    applied: a valid .npz with other bytes."""
    with np.load(io.BytesIO(path.read_bytes() if data is None else data), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    head = json.loads(str(arrays["header_json"]))
    change(arrays, head)
    arrays["header_json"] = np.asarray(json.dumps(head))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, arr in arrays.items():
            with zf.open(f"{name}.npy", "w") as fh:
                np.lib.format.write_array(fh, np.asanyarray(arr), allow_pickle=False)
    path.write_bytes(buf.getvalue())

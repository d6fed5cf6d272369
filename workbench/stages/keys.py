"""Cache keys from what a stage consumes: a digest of its input objects (parameter models,
frozen dataclasses such as the camera geometry, plain values).

A model is digested without the fields left at their defaults, so that a later version adding a
field (a new scene switch, off by default) gives the same keys and data-set fingerprints as
before for every project that does not use it: data sets made earlier still resume."""
from __future__ import annotations

import dataclasses
import hashlib
import json

from pydantic import BaseModel


def _plain(obj):
    if isinstance(obj, BaseModel):          # defaults left out: a new switch, off, keeps old keys
        return {"__model__": type(obj).__qualname__, **obj.model_dump(mode="json", exclude_defaults=True)}
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {"__dataclass__": type(obj).__qualname__,
                **{f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}}
    raise TypeError(f"cache key: cannot digest a {type(obj).__name__}; pass parameter models, "
                    "frozen dataclasses or plain values")


def digest(*parts) -> str:
    """SHA-1 of the parts as canonical JSON (floats written exactly, models with their type name)."""
    text = json.dumps(parts, sort_keys=True, default=_plain, allow_nan=True)
    return hashlib.sha1(text.encode()).hexdigest()

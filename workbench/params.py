"""Base class for every validated parameter model (project-file sections and GUI forms)."""
from __future__ import annotations

import types
import typing

from pydantic import BaseModel, ConfigDict, model_validator


def _holds_tuple(annotation) -> bool:
    """Whether a field annotation is a tuple, or a union (Optional) with a tuple in it."""
    origin = typing.get_origin(annotation)
    if origin is tuple:
        return True
    return origin in (typing.Union, types.UnionType) and any(_holds_tuple(a) for a in typing.get_args(annotation))


class Params(BaseModel):
    """Strict, immutable pydantic model: unknown fields are refused, instances are frozen (edit
    with `updated`), floats must be finite, and numbers are not coerced from bools or strings.

    Field names carry their unit (`exposure_s`, `pixel_pitch_um`); `Field(ge=, le=)` holds the
    allowed range so that a bad value is refused with the field, the value and the range, and
    `description=` says the unit and which model reads the field (the GUI's forms show it).
    JSON lists still load into tuple fields and integers into float fields."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, strict=True)

    @model_validator(mode="before")
    @classmethod
    def _json_arrays_as_tuples(cls, data):
        """A JSON array (a Python list after json.loads) is a tuple field's spelling in a project file."""
        if not isinstance(data, dict):
            return data
        fixed = {name: tuple(data[name]) for name, f in cls.model_fields.items()
                 if isinstance(data.get(name), list) and _holds_tuple(f.annotation)}
        return {**data, **fixed} if fixed else data

    def updated(self, **changes):
        """A validated copy with some fields changed (model_copy(update=…) would skip validation)."""
        data = self.model_dump()
        data.update({k: v.model_dump() if isinstance(v, BaseModel) else v for k, v in changes.items()})
        return type(self).model_validate(data)

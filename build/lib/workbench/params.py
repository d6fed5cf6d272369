"""Base class for every validated parameter model (project-file sections and GUI forms)."""
from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class Params(BaseModel):
    """Strict pydantic model: unknown fields are refused, assignments are re-validated.

    Field names carry their unit (`exposure_s`, `pixel_pitch_um`); `Field(ge=, le=)` holds the
    allowed range so that a bad value is refused with the field, the value and the range."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True, frozen=False)

    def updated(self, **changes):
        """A validated copy with some fields changed (model_copy(update=…) would skip validation)."""
        data = self.model_dump()
        data.update({k: v.model_dump() if isinstance(v, BaseModel) else v for k, v in changes.items()})
        return type(self).model_validate(data)

"""Base class for every validated parameter model (project-file sections and GUI forms)."""
from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class Params(BaseModel):
    """Strict pydantic model: unknown fields are refused, assignments are re-validated.

    Field names carry their unit (`exposure_s`, `pixel_pitch_um`); `Field(ge=, le=)` holds the
    allowed range so that a bad value is refused with the field, the value and the range."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True, frozen=False)

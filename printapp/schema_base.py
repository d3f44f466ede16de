"""The base of every table of a design file: strict types, no unknown keys, finite floats, units.

A file may give a length in micrometres (``amplitude_um = 300``) or an angle in degrees
(``angle_deg = 30``); such keys are converted once, here, to the ``_mm`` / ``_rad`` field
that the model declares.
"""

from __future__ import annotations

import math
from typing import Any

from pydantic import BaseModel, ConfigDict, model_validator

# Unit suffixes a file may use, mapped to the internal field's suffix and the factor
# that converts to it.
UNIT_ALIASES: dict[str, tuple[str, float]] = {
    "_um": ("_mm", 1e-3),
    "_cm": ("_mm", 10.0),
    "_deg": ("_rad", math.pi / 180.0),
}


class Section(BaseModel):
    """Base for every table of the design file: strict types, no unknown keys, finite floats."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True)

    @model_validator(mode="before")
    @classmethod
    def _convert_units(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        out: dict[str, Any] = {}
        for key, value in data.items():
            target = key
            for suffix, (internal, factor) in UNIT_ALIASES.items():
                stem = key[: -len(suffix)] if isinstance(key, str) and key.endswith(suffix) else None
                if stem is not None and stem + internal in cls.model_fields:
                    target = stem + internal
                    if target in data:
                        raise ValueError(f"give either '{key}' or '{target}', not both")
                    if isinstance(value, (int, float)) and not isinstance(value, bool):
                        value = float(value) * factor
                    break
            out[target] = value
        return out

"""Appearance targets in their several forms, and the ``[solve]`` table of a design.

A target of ``[appearance]`` is ``[min, max]``, or ``{ value = V, tolerance = T }``,
``{ min = A }``, ``{ max = B }``; :func:`target_range` turns each into ``[min, max]``.
``[solve]`` names what ``printapp solve`` may change and within which bounds
(:class:`Solve`).
"""

from __future__ import annotations

import math
from typing import Annotated, Any

import annotated_types as at
from pydantic import Field, field_validator, model_validator

from printapp.schema_base import Section
from printapp.schema_errors import short_repr

TARGET_LIMITS: dict[str, tuple[float, float]] = {
    "roughness": (0.0, 1000.0),
    "anisotropy": (1.0, 1000.0),
    "gloss_20": (0.0, 200.0),
    "gloss_60": (0.0, 200.0),
    "gloss_85": (0.0, 200.0),
    "haze": (0.0, 200.0),
    "highlight_azimuth_deg": (0.0, 180.0),
}
"""Each appearance target's widest range: what a one-sided or clipped target extends to."""


def target_range(name: str, value: Any) -> Any:
    """A target written ``{ value = V, tolerance = T }``, ``{ min = A }``, ``{ max = B }`` or
    ``{ min = A, max = B }`` as ``[min, max]``; any other value is left to the field's own check."""
    if not isinstance(value, dict):
        return value
    lo_limit, hi_limit = TARGET_LIMITS[name]
    keys = set(value)

    def number(key: str) -> float:
        v = value[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValueError(f"'{name}.{key}': expected a number, got {short_repr(v)}")
        return float(v)

    if keys == {"value", "tolerance"}:
        centre, tol = number("value"), number("tolerance")
        if tol < 0:
            raise ValueError(f"'{name}.tolerance': expected a tolerance >= 0, got {tol:g}")
        lo, hi = centre - tol, centre + tol
        if name == "highlight_azimuth_deg" and (lo < 0.0 or hi > 180.0):
            raise ValueError(
                f"'{name}': {centre:g} +- {tol:g} crosses the ends of [0, 180] degrees; "
                "give it as [min, max] on one side"
            )
        return [max(lo, lo_limit), min(hi, hi_limit)]
    if keys and keys <= {"min", "max"}:
        lo = number("min") if "min" in keys else lo_limit
        hi = number("max") if "max" in keys else hi_limit
        return [lo, hi]
    raise ValueError(
        f"'{name}': expected [min, max], {{ value = V, tolerance = T }}, {{ min = A }} or {{ max = B }}, "
        f"got a table with {', '.join(sorted(map(str, keys))) or 'no keys'}"
    )


SOLVE_KINDS = ("scn", "fbm", "turbulence")
"""Texture kinds ``printapp solve`` may choose among (those whose slopes the free parameters control)."""


def _bounds(name: str, pair: tuple[float, float] | None, lo: float, hi: float, unit: str = "") -> None:
    if pair is None:
        return
    if pair[0] > pair[1]:
        raise ValueError(f"'{name}' must be [min, max] with min <= max, got [{pair[0]:g}, {pair[1]:g}]")
    if pair[0] < lo or pair[1] > hi:
        raise ValueError(f"'{name}' must lie within [{lo:g}, {hi:g}]{unit}, got [{pair[0]:g}, {pair[1]:g}]")


RANGE_KEYS = ("amplitude_um", "feature_size_mm", "stretch", "angle_deg", "octaves", "pixel_texture_um")
"""The ``[solve]`` keys given as a range ``[min, max]``."""


class Solve(Section):
    """What ``printapp solve`` may change to meet ``[appearance]``, and how hard it searches.

    Each free parameter is given as its bounds ``[min, max]`` (a parameter left out keeps the
    design's value): ``amplitude_um`` (relief.amplitude), ``feature_size_mm``, ``stretch``,
    ``angle_deg``, ``octaves`` (texture), ``kind`` (a list of texture kinds to choose among),
    ``grey_levels`` (``[false, true]`` to let the solver decide, or a fixed ``true``/``false``)
    and ``pixel_texture_um`` (relief.pixel_texture). Keys are in the units their names say.
    """

    amplitude_um: tuple[float, float] | None = Field(default=None, strict=False)
    feature_size_mm: tuple[float, float] | None = Field(default=None, strict=False)
    stretch: tuple[float, float] | None = Field(default=None, strict=False)
    angle_deg: tuple[float, float] | None = Field(default=None, strict=False)
    octaves: tuple[int, int] | None = Field(default=None, strict=False)
    kind: tuple[str, ...] | None = Field(default=None, strict=False)
    grey_levels: tuple[bool, ...] | None = Field(default=None, strict=False)
    """``true``/``false`` fixes the choice (kept as a list of one); ``[false, true]``: the solver decides."""
    pixel_texture_um: tuple[float, float] | None = Field(default=None, strict=False)
    seed: Annotated[int, at.Ge(0), at.Lt(2**32)] = 0
    """Seed of the optimiser: the same design and seed give the same search and result."""
    evaluations: Annotated[int, at.Ge(8), at.Le(100_000)] = 160
    """Surrogate evaluations per round at most."""
    confirm: Annotated[int, at.Ge(1), at.Le(64)] = 2
    """Best candidates traced (the true predicted BRDF) after each round."""
    rounds: Annotated[int, at.Ge(1), at.Le(20)] = 3
    """Rounds of search; after each, the targets are corrected by the gap between surrogate and tracer."""

    @field_validator("grey_levels", mode="before")
    @classmethod
    def _one_choice(cls, value: Any) -> Any:
        return [value] if isinstance(value, bool) else value

    @model_validator(mode="after")
    def _check_bounds(self) -> Solve:
        _bounds("amplitude_um", self.amplitude_um, 1e-3, 50_000.0, " um")
        _bounds("feature_size_mm", self.feature_size_mm, 1e-3, 1000.0, " mm")
        _bounds("stretch", self.stretch, 1.0, 100.0)
        _bounds("angle_deg", self.angle_deg, -360.0, 360.0, " degrees")
        _bounds("pixel_texture_um", self.pixel_texture_um, 0.0, 1000.0, " um")
        if self.octaves is not None:
            _bounds("octaves", (float(self.octaves[0]), float(self.octaves[1])), 1.0, 16.0)
        if self.amplitude_um is not None and self.amplitude_um[0] <= 0:
            raise ValueError("'amplitude_um' must be above 0")
        if self.kind is not None:
            bad = [k for k in self.kind if k not in SOLVE_KINDS]
            if not self.kind or bad or len(set(self.kind)) != len(self.kind):
                raise ValueError(
                    f"'kind' must list distinct texture kinds among {', '.join(SOLVE_KINDS)}, "
                    f"got {short_repr(list(self.kind))}"
                )
        if self.grey_levels is not None and (
            not self.grey_levels or len(set(self.grey_levels)) != len(self.grey_levels)
        ):
            given = short_repr(list(self.grey_levels))
            raise ValueError(f"'grey_levels' must be true, false or [false, true], got {given}")
        return self

    def free(self) -> list[str]:
        """The parameters the solver may change (those given with a range wider than a point)."""
        names = []
        for name in (
            "amplitude_um",
            "feature_size_mm",
            "stretch",
            "angle_deg",
            "octaves",
            "pixel_texture_um",
        ):
            pair = getattr(self, name)
            if pair is not None and pair[0] < pair[1]:
                names.append(name)
        if self.kind is not None and len(self.kind) > 1:
            names.append("kind")
        if self.grey_levels is not None and len(self.grey_levels) > 1:
            names.append("grey_levels")
        return names

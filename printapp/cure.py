"""Cure constants of the resins (the ``[cure.NAME]`` tables of the material catalogue) and the cure
model of a design's ``[material]``.

The numerics live in :mod:`slicing.printed` (:class:`slicing.printed.CureModel`); this module
reads the catalogue and turns a design's choices into a model, with one sentence naming the
key when something does not fit.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

from slicing.printed import CureModel

DEFAULT_RESIN = "acrylate"
"""The catalogue's cure entry for a design that names no material (or one without an entry)."""


@dataclass(frozen=True)
class CureConstants:
    """One ``[cure.NAME]`` entry: Jacobs' working-curve constants and the dose of a fully lit pixel."""

    name: str
    penetration_depth_mm: float
    critical_dose_mj_cm2: float
    dose_mj_cm2: float
    description: str = ""
    source: str = ""


@lru_cache(maxsize=1)
def catalogue_cure() -> dict[str, CureConstants]:
    """Every ``[cure.NAME]`` entry of the built-in catalogue (``printapp/data/materials.toml``)."""
    from printapp.materials import CATALOGUE, MaterialError
    from printapp.tomlfile import read_toml

    raw = read_toml(CATALOGUE, "materials.toml", "material", MaterialError).get("cure", {})
    keys = {"penetration_depth_um", "critical_dose_mj_cm2", "dose_mj_cm2", "description", "source"}
    out = {}
    for name, entry in raw.items():
        where = f"materials.toml: cure.{name}"
        if not isinstance(entry, dict) or set(entry) - keys:
            raise MaterialError(f"{where}: expected a table of {', '.join(sorted(keys))}")
        numbers = []
        for key in ("penetration_depth_um", "critical_dose_mj_cm2", "dose_mj_cm2"):
            value = entry.get(key)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
                raise MaterialError(f"{where}.{key}: expected a positive number, got {value!r}")
            numbers.append(float(value))
        out[name] = CureConstants(
            name,
            numbers[0] / 1000.0,
            numbers[1],
            numbers[2],
            str(entry.get("description", "")),
            str(entry.get("source", "")),
        )
    return out


def resin_constants(material_name: str | None) -> CureConstants:
    """The cure entry named like the material, else :data:`DEFAULT_RESIN`'s."""
    table = catalogue_cure()
    if material_name is not None and material_name in table:
        return table[material_name]
    return table[DEFAULT_RESIN]


def build_cure_model(
    kind: str,
    material_name: str | None,
    penetration_depth_mm: float | None = None,
    critical_dose_mj_cm2: float | None = None,
    dose_mj_cm2: float | None = None,
) -> CureModel:
    """The cure model of a ``[material]`` table: ``kind`` with the catalogue's constants, overridden.

    Raises
    ------
    ValueError
        Naming the ``[material]`` key, when a fully lit pixel would cure nothing.
    """
    if kind == "linear":
        return CureModel.linear()
    base = resin_constants(material_name)
    dp = base.penetration_depth_mm if penetration_depth_mm is None else penetration_depth_mm
    ec = base.critical_dose_mj_cm2 if critical_dose_mj_cm2 is None else critical_dose_mj_cm2
    dose = base.dose_mj_cm2 if dose_mj_cm2 is None else dose_mj_cm2
    if not dose > ec:
        key = "dose_mj_cm2" if dose_mj_cm2 is not None else "critical_dose_mj_cm2"
        raise ValueError(
            f"'{key}': a fully lit pixel's dose ({dose:g} mJ/cm^2) must exceed the critical dose "
            f"({ec:g} mJ/cm^2), or it cures nothing"
        )
    return CureModel.working_curve(dp, ec, dose)


def check_layer_bonds(model: CureModel, layer_mm: float) -> str | None:
    """Why a fully lit pixel would not cure through a layer of ``layer_mm`` (None when it does)."""
    if model.kind == "linear" or model.full_cure_depth_mm >= layer_mm * (1.0 - 1e-9):
        return None
    return (
        f"a fully lit pixel cures {model.full_cure_depth_mm * 1000:.3g} um, less than the "
        f"{layer_mm * 1000:.3g} um layer: its layers would not bond (raise dose_mj_cm2)"
    )


def describe_constants(model: CureModel) -> dict[str, float | str]:
    """The model's name and constants, for the manifest."""
    if model.kind == "linear":
        return {"model": "linear"}
    return {
        "model": "working-curve",
        "penetration_depth_um": round(model.penetration_depth_mm * 1000.0, 6),
        "critical_dose_mj_cm2": model.critical_dose,
        "dose_mj_cm2": model.full_dose,
        "full_cure_depth_um": round(model.full_cure_depth_mm * 1000.0, 4),
        "threshold_grey": round(model.threshold_grey(), 3),
    }

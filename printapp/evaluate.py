"""One design evaluated as far as asked: the unit of work of ``printapp sweep`` and ``printapp solve``.

Three levels, each a pure function of the resolved design (and so cacheable by its hash):

* ``surrogate``: the as-printed relief (sliced and cured as ``printapp design`` makes it)
  and the glossmeter on its facets (:func:`render.facets.facet_appearance`), about a second;
* ``brdf``: that, and the gloss, haze and highlight traced through the relief, the numbers
  ``printapp design`` reports (:func:`traced_metrics`; without the compact model's fit);
* ``design``: that, and the whole ``printapp design`` run into a folder (model, slices,
  preview, report), whose verification verdict is the point's.

Metrics come back as plain floats (rounded to 6 decimals), so that a table of them is the same
bytes wherever and however often it is computed.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

from printapp.design import Design, TileBase

LEVELS = ("surrogate", "brdf", "design")
"""How far a design is evaluated, cheapest first."""

SURROGATE_METRICS = (
    "gloss_20",
    "gloss_60",
    "gloss_85",
    "haze",
    "anisotropy",
    "highlight_azimuth_deg",
    "roughness",
    "flat_fraction",
)
"""What the surrogate reports (as ``surrogate_NAME`` columns)."""
TRACED_METRICS = ("gloss_20", "gloss_60", "gloss_85", "haze", "highlight_azimuth_deg", "highlight_anisotropy")
"""What the traced BRDF reports."""
TARGETS = ("roughness", "anisotropy", "gloss_20", "gloss_60", "gloss_85", "haze", "highlight_azimuth_deg")
"""The ``[appearance]`` targets, in the order they are reported."""
SLOPE_TARGETS = ("roughness", "anisotropy")
"""Targets checked against the as-printed relief's slopes (as ``printapp design`` checks them)."""


def _round(value: float) -> float:
    return round(float(value), 6) if math.isfinite(value) else 1e300


def printability_reasons(design: Design) -> list[str]:
    """What keeps the design from printing as designed (``printapp design``'s relief checks and the cure)."""
    from printapp.cure import check_layer_bonds
    from printapp.relief import cure_model

    reasons = []
    profile = design.printer.profile
    lh = design.layer_height_mm
    if design.relief.amplitude_mm < lh:
        reasons.append(
            f"relief.amplitude_mm {design.relief.amplitude_mm:g} is less than one layer ({lh:g} mm)"
        )
    if design.texture.feature_size_mm < 2.0 * profile.pitch_mm:
        reasons.append(
            f"texture.feature_size_mm {design.texture.feature_size_mm:g} is below two printer pixels "
            f"({2.0 * profile.pitch_mm:.3f} mm)"
        )
    bond = check_layer_bonds(cure_model(design), lh)
    if bond is not None:
        reasons.append(bond)
    return reasons


def target_misses(design: Design, metrics: dict[str, float]) -> list[str]:
    """Each ``[appearance]`` target the metrics miss, in ``printapp design``'s words.

    Gloss, haze and the highlight's azimuth are read from the traced BRDF where it was traced,
    else from the surrogate; roughness and anisotropy from the as-printed relief's slopes.
    """
    misses = []
    for name in TARGETS:
        target = getattr(design.appearance, name)
        if target is None:
            continue
        key = name if name in metrics and name not in SLOPE_TARGETS else f"surrogate_{name}"
        value = metrics[key]
        lo, hi = target
        if value is None:  # haze where ASTM D4039 does not define it (G60 not above 70 GU)
            misses.append(f"{name} cannot be checked against the target [{lo:g}, {hi:g}]: it is n/a here")
            continue
        if not lo <= value <= hi:
            miss = (lo - value) if value < lo else (value - hi)
            misses.append(f"{name} {value:.2f} misses the target [{lo:g}, {hi:g}] by {miss:.2f}")
    return misses


def traced_metrics(design: Design, field: Any) -> dict[str, Any]:
    """The traced gloss, haze and highlight ``printapp design`` reports for ``field``, without the
    compact model's fit (:func:`render.traced.traced_gloss`; the whole prediction when the design
    asks for a lobe error, whose ray budget only the whole table sets)."""
    from printapp.rendering import predict_for_design, tracer_options

    if design.brdf.lobe_error is not None:
        return predict_for_design(design, field).metrics
    from render.traced import traced_gloss

    return traced_gloss(field, **tracer_options(design))


def evaluate_design(
    design: Design, level: str = "surrogate", out_dir: str | Path | None = None
) -> dict[str, Any]:
    """Evaluate ``design`` up to ``level`` (see the module); ``out_dir`` receives a ``design`` run.

    Returns
    -------
    dict
        ``metrics`` (``surrogate_*`` always, the traced ones from ``brdf`` up), ``verdict``
        (``"pass"`` or ``"fail"``), ``reasons`` (what failed) and ``seconds`` per stage.

    Raises
    ------
    PrintappError
        If the design cannot be built (e.g. over the memory budget), naming the setting.
    """
    from printapp.brdf import grey_albedo
    from printapp.material_design import derive_design_material
    from printapp.relief import appearance_field, build_relief
    from render.facets import facet_appearance

    if level not in LEVELS:
        raise ValueError(f"level: expected one of {', '.join(LEVELS)}, got {level!r}")
    seconds: dict[str, float] = {}
    start = time.perf_counter()
    resolved, _ = derive_design_material(design)
    relief = build_relief(resolved)
    field, _ = appearance_field(resolved, relief)
    seconds["relief"] = time.perf_counter() - start
    start = time.perf_counter()
    surrogate = facet_appearance(
        field,
        ior=resolved.material.refractive_index,
        body_albedo=grey_albedo(resolved.material.body_albedo),
        n_theta=resolved.brdf.theta_bins,
        n_phi=resolved.brdf.phi_bins,
    )
    seconds["surrogate"] = time.perf_counter() - start
    metrics = {f"surrogate_{k}": _round(surrogate[k]) for k in SURROGATE_METRICS}
    reasons = printability_reasons(resolved)
    if level in ("brdf", "design"):
        start = time.perf_counter()
        traced = traced_metrics(resolved, field)
        seconds["brdf"] = time.perf_counter() - start
        gloss = traced["gloss_gu"]
        metrics.update(
            {
                "gloss_20": _round(gloss["20"]),
                "gloss_60": _round(gloss["60"]),
                "gloss_85": _round(gloss["85"]),
                "haze": None if traced["haze"] is None else _round(traced["haze"]),
                "highlight_azimuth_deg": _round(traced["highlight"]["azimuth_deg"]),
                "highlight_anisotropy": _round(traced["highlight"]["anisotropy"]),
            }
        )
    reasons += target_misses(resolved, metrics)
    if level == "design":
        from printapp.pipeline import run_design

        assert out_dir is not None, "a design run needs an output folder"
        start = time.perf_counter()
        outcome = run_design(design, out_dir, quiet=True)
        seconds["design"] = time.perf_counter() - start
        reasons = list(outcome.reasons)
    return {
        "metrics": metrics,
        "verdict": "pass" if not reasons else "fail",
        "reasons": reasons,
        "seconds": {k: round(v, 4) for k, v in seconds.items()},
    }


def evaluate_resolved(resolved_text: str, level: str, out_dir: str | None = None) -> dict[str, Any]:
    """:func:`evaluate_design` of a ``design.resolved.toml`` text: what a sweep's worker runs.

    A design that cannot be built comes back with the verdict ``"refused"`` and its sentence
    (e.g. over the worker's memory budget) instead of raising.
    """
    import tomllib

    from printapp.design import design_from_dict
    from printapp.errors import PrintappError

    try:
        design = design_from_dict(tomllib.loads(resolved_text), "design.resolved.toml")
        return evaluate_design(design, level, out_dir)
    except PrintappError as exc:
        return {"metrics": {}, "verdict": "refused", "reasons": [str(exc)], "seconds": {}}


def is_tile(design: Design) -> bool:
    """Whether the design's appearance comes from an as-printed relief (a tile without booleans)."""
    return isinstance(design.base, TileBase) and not design.combine

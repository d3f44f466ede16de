"""A design's named material: its derived index and albedo, and how its preview renders it."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from printapp.materials import appearance, find_material, resolve_parameters

if TYPE_CHECKING:
    from printapp.design import Design
    from render.translucency import Appearance, MediumRGB


@dataclass(frozen=True)
class DesignMaterial:
    """A design's named material: its computed appearance, for the pipeline and the manifest."""

    name: str
    parameters: dict[str, float]
    appearance: Appearance
    """:class:`render.translucency.Appearance`."""


def derive_design_material(design: Design) -> tuple[Design, DesignMaterial | None]:
    """For a design whose material has a ``name``: the design with the derived refractive index
    and body albedo filled in (so every later stage uses them), and the material's appearance.

    A design without a named material comes back unchanged, with ``None``.
    """
    material = design.material
    if material.name is None:
        return design, None
    look = appearance(material.name, dict(material.parameters))
    derived = material.model_copy(
        update={
            "refractive_index": float(min(max(look.refractive_index, 1.0), 3.0)),
            "body_albedo": tuple(float(min(max(c, 0.0), 1.0)) for c in look.body_albedo),
        }
    )
    values = resolve_parameters(find_material(material.name)[0], dict(material.parameters))
    return design.model_copy(update={"material": derived}), DesignMaterial(material.name, values, look)


def render_choice(
    design: Design, chosen: DesignMaterial | None, vertices_mm: np.ndarray
) -> tuple[MediumRGB | None, dict[str, Any] | None]:
    """The medium to render (or None for the body albedo) and the manifest's record of why.

    ``translucency = "auto"`` compares the material's largest transport mean free path with the
    preview's pixel footprint on the object (:func:`render.translucency.choose_translucency`).
    """
    from render.mitsuba_adapter import PREVIEW_FOV_DEG, Framing
    from render.translucency import MEDIUM_THRESHOLD, choose_translucency

    if chosen is None:
        return None, None
    look = chosen.appearance
    r = design.render
    # The preview's own camera: the footprint of one of its pixels on the object.
    footprint = Framing.of(
        np.asarray(vertices_mm, dtype=np.float64), r.width_px, r.height_px, PREVIEW_FOV_DEG, r.distance_scale
    ).pixel_footprint_mm
    mode = design.material.translucency
    kind = choose_translucency(look.transport_mfp_mm, footprint) if mode == "auto" else mode
    record = {
        "name": chosen.name,
        "parameters": chosen.parameters,
        "method": "Lorenz-Mie (Frisvad, Christensen & Jensen 2007), reduced to linear RGB",
        "refractive_index": round(look.refractive_index, 6),
        "body_albedo": [round(c, 6) for c in look.body_albedo],
        "sigma_s_per_mm": [round(c, 6) for c in look.medium.sigma_s_per_mm],
        "sigma_a_per_mm": [round(c, 8) for c in look.medium.sigma_a_per_mm],
        "g": round(look.medium.g, 6),
        "transport_mfp_mm": [round(c, 6) if math.isfinite(c) else None for c in look.transport_mfp_mm],
        "pixel_footprint_mm": round(footprint, 6),
        "translucency": mode,
        "rendered_as": "homogeneous medium in a dielectric" if kind == "medium" else "body albedo (plastic)",
        "threshold_mfp_over_footprint": MEDIUM_THRESHOLD,
    }
    return (look.medium if kind == "medium" else None), record

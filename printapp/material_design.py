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


RENDERED_AS = {
    "medium": "homogeneous medium in a dielectric",
    "bssrdf": "BSSRDF: the light that enters diffused through the tile (render.subsurface)",
    "albedo": "body albedo (plastic)",
}


def tile_box_mm(design: Design) -> tuple[float, float, float] | None:
    """A tile's box (thickness, depth, width in mm) for the BSSRDF; None for meshes and booleans."""
    from printapp.design import TileBase

    if not isinstance(design.base, TileBase) or design.combine:
        return None
    b = design.base
    return (b.thickness_mm, b.depth_mm, b.width_mm)


def render_choice(
    design: Design, chosen: DesignMaterial | None, vertices_mm: np.ndarray
) -> tuple[MediumRGB | None, dict[str, Any] | None, str]:
    """The medium to render (None for the body albedo), the manifest's record of why, and the
    representation: ``"albedo"``, ``"bssrdf"`` or ``"medium"``.

    ``translucency = "auto"`` compares the material's largest transport mean free path with the
    preview's pixel footprint on the object and, for a tile, with its thickness
    (:func:`render.translucency.choose_translucency`). The BSSRDF is rendered for tiles only,
    and only where its diffusion grid resolves the mean free path; elsewhere the medium.
    """
    from render.mitsuba_adapter import PREVIEW_FOV_DEG, Framing
    from render.subsurface import resolves
    from render.translucency import BSSRDF_MAX_MFP_OVER_THICKNESS, MEDIUM_THRESHOLD, choose_translucency

    if chosen is None:
        return None, None, "albedo"
    look = chosen.appearance
    r = design.render
    # The preview's own camera: the footprint of one of its pixels on the object.
    footprint = Framing.of(
        np.asarray(vertices_mm, dtype=np.float64), r.width_px, r.height_px, PREVIEW_FOV_DEG, r.distance_scale
    ).pixel_footprint_mm
    mode = design.material.translucency
    box = tile_box_mm(design)
    shortest = float(min(look.transport_mfp_mm))
    usable = box is not None and math.isfinite(shortest) and resolves(box, shortest)
    why = 'chosen by the transport mean free path (translucency = "auto")'
    if mode == "auto":
        kind = choose_translucency(look.transport_mfp_mm, footprint, thickness_mm=box[0] if usable else None)
        if kind == "medium" and not usable:
            why += "; the BSSRDF is rendered for tiles whose diffusion grid resolves the mean free path only"
    else:
        kind = mode
        why = f'asked for in the design (translucency = "{mode}")'
    if kind == "bssrdf" and not usable:
        from printapp.errors import PrintappError

        raise PrintappError(
            'material.translucency = "bssrdf": the BSSRDF is rendered for tiles (without booleans) '
            'whose diffusion grid resolves the transport mean free path only; use "medium" or "auto"'
        )
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
        "rendered_as": RENDERED_AS[kind],
        "why": why,
        "threshold_mfp_over_footprint": MEDIUM_THRESHOLD,
        "bssrdf_up_to_mfp_over_thickness": BSSRDF_MAX_MFP_OVER_THICKNESS,
        "thickness_mm": None if box is None else box[0],
    }
    return (None if kind == "albedo" else look.medium), record, kind

"""Renders of a design: the chosen representation of its relief, the preview, the light sweep."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import trimesh

from noise.heightfield import HeightField
from printapp.brdf import grey_albedo
from printapp.design import Design, TileBase
from printapp.mesh import slab_from_heightfield

if TYPE_CHECKING:
    from printapp.relief import Relief
    from render.appearance import Appearance
    from render.mitsuba_adapter import StudioLight
    from render.mitsuba_bsdfs import TableSurface
    from render.translucency import MediumRGB


@dataclass
class Preview:
    """A rendered preview and how it was made."""

    image: np.ndarray
    mode: str
    reason: str
    pixels_per_feature: float
    variant: str
    warning: str | None


def predict_for_design(design: Design, field: HeightField) -> Appearance:
    """The predicted appearance (:func:`render.appearance.predict_appearance`) of a design's relief."""
    from render.appearance import predict_appearance

    return predict_appearance(
        field,
        ior=design.material.refractive_index,
        body_albedo=grey_albedo(design.material.body_albedo),
        rays=design.brdf.rays,
        n_theta=design.brdf.theta_bins,
        n_phi=design.brdf.phi_bins,
        seed=design.brdf.seed,
        distribution=design.brdf.distribution,
        lobe_error_target=design.brdf.lobe_error,
    )


def base_shape(design: Design, relief: Relief) -> trimesh.Trimesh | None:
    """The smooth shape under the relief, for the BRDF representations (None with booleans).

    A tile's base is the slab at the relief's mean height (so that it stands where the
    relief's average surface does); a mesh's is the refined mesh before displacement.
    """
    if design.combine:
        return None
    if isinstance(design.base, TileBase):
        patch = relief.patch
        level = float(np.mean(patch.heights_mm))
        flat = HeightField(
            np.full((2, 2), level), patch.width_mm, patch.depth_mm, patch.origin_x_mm, patch.origin_y_mm
        )
        return slab_from_heightfield(flat, design.base.thickness_mm)
    return relief.undisplaced


def render_preview(
    design: Design,
    relief: Relief,
    mesh: trimesh.Trimesh,
    predicted: Appearance,
    appearance_field: HeightField,
    *,
    medium: MediumRGB | None = None,
    light: StudioLight | None = None,
    tables: dict[str, TableSurface] | None = None,
) -> Preview:
    """Path-trace the design with the representation its camera needs (``design.render.mode``).

    ``predicted`` is the :class:`render.appearance.Appearance` of ``appearance_field``
    (the as-printed relief for tiles). A translucent ``medium`` lives inside the real
    object, so it is always rendered as geometry; so are designs with booleans (no
    smooth base), and previews on Mitsuba's scalar variant (the BRDF plugins are Python
    code, which only the vectorised variants run at speed). ``tables`` keeps a traced
    table between calls (a light sweep renders the same surface several times).
    """
    from render.mitsuba_adapter import PREVIEW_FOV_DEG, Framing, choose_variant, render_resin_mesh
    from render.representation import Choice, choose_representation, compact_surface, table_surface

    variant = choose_variant()
    r = design.render
    frame = Framing.of(np.asarray(mesh.vertices), r.width_px, r.height_px, PREVIEW_FOV_DEG, r.distance_scale)
    feature = design.texture.feature_size_mm
    pixels = feature / frame.pixel_footprint_mm
    base = base_shape(design, relief)
    if medium is not None:
        choice = Choice(
            "geometry", "a translucent resin is rendered as the real object with its medium", pixels
        )
    elif base is None:
        choice = Choice("geometry", "booleans leave no smooth base shape for a BRDF", pixels)
    elif r.mode != "auto":
        choice = Choice(r.mode, "asked for in the design", pixels)
    elif variant.variant == "scalar_rgb":
        choice = Choice("geometry", "Mitsuba's scalar variant runs the BRDF plugins too slowly", pixels)
    else:
        choice = choose_representation(feature, frame.pixel_footprint_mm, predicted.fit.relative_error)
    surface = None
    target = mesh
    rgb = design.material.body_albedo
    grey = grey_albedo(rgb)
    if choice.mode == "model":
        surface = compact_surface(predicted.fit.model, rgb, grey)
        target = base
    elif choice.mode == "table" and tables is not None and "table" in tables:
        surface, target = tables["table"], base
    elif choice.mode == "table":
        surface = table_surface(
            appearance_field.heights_mm,
            appearance_field.pitch_x_mm,
            appearance_field.pitch_y_mm,
            ior=design.material.refractive_index,
            body_rgb=rgb,
            grey=grey,
            rays=max(2_000, design.brdf.rays // 5),
            n_theta=design.brdf.theta_bins,
            n_phi=design.brdf.phi_bins,
            seed=design.brdf.seed,
        )
        target = base
        if tables is not None:
            tables["table"] = surface
    image = render_resin_mesh(
        np.asarray(target.vertices),
        np.asarray(target.faces),
        body_albedo=rgb,
        refractive_index=design.material.refractive_index,
        width_px=r.width_px,
        height_px=r.height_px,
        spp=r.spp,
        seed=r.seed,
        elevation_rad=r.elevation_rad,
        azimuth_rad=r.azimuth_rad,
        fov_deg=PREVIEW_FOV_DEG,
        light=light,
        medium=medium,
        surface=surface,
        distance_scale=r.distance_scale,
        frame_vertices=np.asarray(mesh.vertices),
    )
    return Preview(image, choice.mode, choice.reason, pixels, variant.variant, variant.warning)


def sweep_azimuths_rad(camera_azimuth_rad: float, frames: int) -> list[float]:
    """The light's azimuths (radians) in a sweep of ``frames``: evenly round, half a step off the camera.

    A light at the camera's own azimuth puts the soft box between the camera and the
    object, and the frame comes out black (it does within about 20 degrees, with the
    default camera and :class:`render.mitsuba_adapter.StudioLight`); half a step off, the
    six-frame sweep's nearest light is 30 degrees from the camera.
    """
    return [camera_azimuth_rad + 2.0 * math.pi * (k + 0.5) / frames for k in range(frames)]


def light_sweep(
    design: Design,
    relief: Relief,
    mesh: trimesh.Trimesh,
    predicted: Appearance,
    appearance_field: HeightField,
    *,
    frames: int = 6,
    width_px: int = 160,
    height_px: int = 120,
    spp: int = 8,
    medium: MediumRGB | None = None,
) -> np.ndarray:
    """The light circling the object in ``frames`` steps, side by side: an anisotropic highlight moves.

    Returns one ``(height_px, frames * width_px, 3)`` linear-RGB strip.
    """
    from render.mitsuba_adapter import StudioLight

    small = design.model_copy(
        update={
            "render": design.render.model_copy(
                update={"width_px": width_px, "height_px": height_px, "spp": spp}
            )
        }
    )
    strip = []
    tables: dict[str, Any] = {}
    for azimuth in sweep_azimuths_rad(design.render.azimuth_rad, frames):
        # Only the soft box moves; the fixed spot would only confuse the sweep.
        light = replace(StudioLight(), azimuth_rad=azimuth, highlight_radiance=0.0)
        strip.append(
            render_preview(
                small, relief, mesh, predicted, appearance_field, medium=medium, light=light, tables=tables
            ).image
        )
    return np.concatenate(strip, axis=1)


def render_design_file(
    design_file: Path,
    out: Path,
    *,
    mode: str = "auto",
    spp: int | None = None,
    distance_scale: float | None = None,
    sweep: Path | None = None,
) -> tuple[Design, Preview, list[Path]]:
    """``printapp render``: path-trace a design's predicted appearance, and optionally a light sweep.

    ``mode``, ``spp`` and ``distance_scale`` override the design's ``[render]`` table
    (None keeps the design's). Both images are written, or neither.
    """
    from printapp.design import load_design
    from printapp.errors import PrintappError
    from printapp.exporters import png_bytes
    from printapp.mesh import combine_solids
    from printapp.outputs import atomic_write_files
    from printapp.relief import appearance_field, build_relief
    from render.mitsuba_adapter import to_srgb8

    for path in (out, sweep):
        if path is not None and path.suffix.lower() != ".png":
            raise PrintappError(f"{path}: expected an image file ending in .png")
    design = load_design(design_file)
    updates: dict[str, Any] = {"mode": mode}
    if spp is not None:
        updates["spp"] = spp
    if distance_scale is not None:
        updates["distance_scale"] = distance_scale
    design = design.model_copy(update={"render": design.render.model_copy(update=updates)})
    relief = build_relief(design)
    mesh = combine_solids(relief.mesh, design.combine) if design.combine else relief.mesh
    field, _ = appearance_field(design, relief)
    predicted = predict_for_design(design, field)
    preview = render_preview(design, relief, mesh, predicted, field)
    outputs = [(out, png_bytes(to_srgb8(preview.image)))]
    if sweep is not None:
        outputs.append((sweep, png_bytes(to_srgb8(light_sweep(design, relief, mesh, predicted, field)))))
    return design, preview, atomic_write_files(outputs)

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
    from render.convergence import Converged
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
    convergence: Converged | None = None
    """How the preview's noise was brought down (None for fixed-sample renders)."""
    denoiser: str = ""
    """The denoiser used or available, or why there is none."""
    object_pixels: int = 0


def noise_record(preview: Preview) -> dict[str, Any] | None:
    """The manifest's account of a preview's noise: raw figure, goal, samples, denoiser, stop."""
    c = preview.convergence
    if c is None:
        return None
    return {
        "estimator": "RMS over the object's pixels of the standard error of the pixel's luminance "
        "(from two independent halves), relative to the object's mean luminance",
        "raw_relative_noise": round(c.noise, 5),
        "target": c.target,
        "converged": c.converged,
        "stopped_by": c.stopped,
        "spp": c.spp,
        "spp_range": list(c.spp_range),
        "passes": c.passes,
        "budget_spp": c.budget_spp,
        "budget_set_by_time_cap": c.timing_dependent,
        "seconds": round(c.seconds, 3),
        "object_pixels": preview.object_pixels,
        "denoised": c.denoised,
        "denoised_error": None if c.denoised_error is None else round(c.denoised_error, 5),
        "denoiser": preview.denoiser,
        "history": [[spp, round(noise, 5)] for spp, noise in c.history],
        "lamp_caustics": (
            f"light-traced: {c.light_paths:,} paths from the lamps (render.caustics)"
            if c.light_paths
            else "path-traced with the rest"
        ),
    }


def noise_summary(preview: Preview) -> tuple[bool, str]:
    """Whether the preview converged (by its raw noise), and one sentence: how far, how, why it stopped."""
    c = preview.convergence
    if c is None:
        return True, "preview rendered with a fixed number of samples"
    low, high = c.spp_range
    spread = f" ({low}-{high}, more where the noise is)" if high > low else ""
    how = f"{c.spp} samples per pixel{spread} in {c.seconds:.1f} s"
    if c.light_paths:
        how += f" (the lamps' caustics light-traced, {c.light_paths / 1e6:.1f} M paths)"
    denoised = ""
    if c.denoised:
        denoised = (
            f"; the preview written is denoised ({c.denoiser}), its error against a converged render "
            f"{c.denoised_error:.1%} (estimated from the independent halves)"
        )
    if c.converged:
        return True, (
            f"preview converged: raw noise {c.noise:.1%} of the object's mean luminance "
            f"(at most {c.target * 100:g}%) after {how}{denoised}"
        )
    stop = {
        "time cap": f"the time cap ({c.time_cap_s:g} s)",
        "sample budget": f"the sample budget ({c.budget_spp} samples per pixel)",
    }.get(c.stopped, c.stopped)
    line = (
        f"preview noise {c.noise:.1%} (raw) is above its threshold {c.target * 100:g}%: rendering stopped at "
        f"{stop} after {how}{denoised}"
    )
    if c.timing_dependent:
        line += "; the number of samples depended on this machine's speed"
    return False, line


def tracer_options(design: Design) -> dict[str, Any]:
    """The traced BRDF's settings a design fixes: the resin's index, the body's grey albedo, the
    rays, the bins and the seed (shared by the full prediction and the glossmeter alone)."""
    return {
        "ior": design.material.refractive_index,
        "body_albedo": grey_albedo(design.material.body_albedo),
        "rays": design.brdf.rays,
        "n_theta": design.brdf.theta_bins,
        "n_phi": design.brdf.phi_bins,
        "seed": design.brdf.seed,
    }


def predict_for_design(design: Design, field: HeightField, analytic: bool = True) -> Appearance:
    """The predicted appearance (:func:`render.appearance.predict_appearance`) of a design's relief;
    without ``analytic``, the analytic fit beside the compact model is left to
    :func:`analytic_for_design`."""
    from render.appearance import predict_appearance

    return predict_appearance(
        field,
        **tracer_options(design),
        distribution=design.brdf.distribution,
        lobe_error_target=design.brdf.lobe_error,
        analytic=analytic,
    )


def analytic_for_design(design: Design, predicted: Appearance) -> Appearance:
    """``predicted`` with its analytic fit (:func:`render.appearance.with_analytic_fit`)."""
    from render.appearance import with_analytic_fit

    return with_analytic_fit(
        predicted, ior=design.material.refractive_index, distribution=design.brdf.distribution
    )


def base_shape(design: Design, relief: Relief) -> trimesh.Trimesh | None:
    """The smooth shape under the relief, for the BRDF representations (None with booleans).

    A tile's base is the slab at the relief's mean height (so that it stands where the
    relief's average surface does); a mesh's is the closed mesh the relief was built on, not
    its refinement: the same surface (:func:`printapp.mesh.refine_to_edge_length` splits
    triangles in their planes) in a few thousand triangles instead of a million, so a light
    sweep's lamp moves no longer rebuild a million-triangle BVH (0.3 s a frame on
    ``brushed_part``) and the scene loads at once.
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
    return relief.base if relief.base is not None else relief.undisplaced


def render_preview(
    design: Design,
    relief: Relief,
    mesh: trimesh.Trimesh,
    predicted: Appearance,
    appearance_field: HeightField,
    *,
    medium: MediumRGB | None = None,
    light: StudioLight | None = None,
    tables: dict[str, Any] | None = None,
    fixed_spp: int | None = None,
    mode_source: str = "in the design",
    translucency: str = "medium",
) -> Preview:
    """Path-trace the design with the representation its camera needs (``design.render.mode``).

    ``predicted`` is the :class:`render.appearance.Appearance` of ``appearance_field``
    (the as-printed relief for tiles). A translucent ``medium`` lives inside the real
    object, so it is always rendered as geometry; so are designs with booleans (no
    smooth base), and previews on Mitsuba's scalar variant (the BRDF plugins are Python
    code, which only the vectorised variants run at speed). ``tables`` keeps a traced
    table, and the loaded scene with its denoiser guides, between calls: a light sweep renders
    the same surface several times, moving only the lamps.

    The preview is rendered in passes until its noise meets ``design.render.noise``
    (:func:`render.convergence.converge`); with ``fixed_spp`` it takes that many samples
    (in two halves, whose noise is still measured), as the light sweep's frames do.
    ``mode_source`` says where a forced ``mode`` came from, for the reason shown. Without
    ``light``, an anisotropic tile's spot stands at the camera's mirror, where its highlight
    shows the streak (:func:`printapp.highlight_check.preview_light`). With
    ``translucency = "bssrdf"`` a tile's ``medium`` is rendered as the light diffused through
    the tile instead (:func:`render.subsurface.subsurface_tile`).
    """
    from printapp.highlight_check import preview_light
    from render.mitsuba_adapter import (
        PREVIEW_FOV_DEG,
        Framing,
        choose_variant,
        lamp_transforms,
        resin_scene_dict,
        studio_places,
    )
    from render.representation import Choice, choose_representation, compact_surface, table_surface

    if light is None:
        light = preview_light(design, predicted.metrics)
    variant = choose_variant()
    r = design.render
    frame = Framing.of(np.asarray(mesh.vertices), r.width_px, r.height_px, PREVIEW_FOV_DEG, r.distance_scale)
    feature = design.texture.feature_size_mm
    pixels = feature / frame.pixel_footprint_mm
    if tables is not None and "base" in tables:
        base = tables["base"]  # the same object each frame: a loaded scene is known by it
    else:
        base = base_shape(design, relief)
        if tables is not None:
            tables["base"] = base
    if medium is not None and translucency == "bssrdf":
        choice = Choice(
            "geometry",
            "a translucent resin is rendered as the real tile, glowing with the light diffused through it "
            "(BSSRDF)",
            pixels,
        )
    elif medium is not None:
        choice = Choice(
            "geometry", "a translucent resin is rendered as the real object with its medium", pixels
        )
    elif base is None:
        choice = Choice("geometry", "booleans leave no smooth base shape for a BRDF", pixels)
    elif r.mode != "auto":
        choice = Choice(r.mode, f"asked for {mode_source}", pixels)
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
    camera = {
        "refractive_index": design.material.refractive_index,
        "width_px": r.width_px,
        "height_px": r.height_px,
        "elevation_rad": r.elevation_rad,
        "azimuth_rad": r.azimuth_rad,
        "fov_deg": PREVIEW_FOV_DEG,
        "light": light,
        "distance_scale": r.distance_scale,
        "frame_vertices": np.asarray(mesh.vertices),
    }

    def load_and_converge(loaded: dict[str, Any] | None) -> tuple[Converged, str, int]:
        scene_dict, _ = resin_scene_dict(
            np.asarray(target.vertices),
            np.asarray(target.faces),
            body_albedo=rgb,
            medium=None if translucency == "bssrdf" else medium,
            surface=surface,
            **camera,
        )
        if medium is not None and translucency == "bssrdf":
            from render.subsurface import eye_of, lights_of, subsurface_tile

            if not isinstance(design.base, TileBase):
                raise ValueError("the BSSRDF is rendered for tiles only")
            p = relief.patch
            vertices, faces, radiance = subsurface_tile(
                p.heights_mm,
                p.pitch_x_mm,
                p.pitch_y_mm,
                p.origin_x_mm,
                p.origin_y_mm,
                design.base.thickness_mm,
                medium,
                design.material.refractive_index,
                lights_of(scene_dict),
                eye_of(scene_dict),
            )
            scene_dict, _ = resin_scene_dict(vertices, faces, body_albedo=rgb, emission=radiance, **camera)
        elif loaded is not None and medium is None:
            # The object as an instance of a shape group: moving a lamp then rebuilds only the
            # top of Mitsuba's BVH, not the object's own (0.2 s against 0.64 s for 1.3 M triangles).
            scene_dict["relief_group"] = {"type": "shapegroup", "relief": scene_dict.pop("relief")}
            scene_dict["relief"] = {"type": "instance", "shapegroup": {"type": "ref", "id": "relief_group"}}
        return _converge(scene_dict, design, fixed_spp, loaded)

    # A light sweep renders one scene under lamps that move: it is loaded once (with its
    # denoiser guides, which no lamp changes) and its lamps are moved between frames. Not
    # with the BSSRDF, whose emission depends on the lamps.
    loaded = tables if tables is not None and translucency != "bssrdf" else None
    # Everything but where the lamps stand must be what the loaded scene was made with.
    still = replace(
        light, azimuth_rad=0.0, elevation_rad=0.0, highlight_azimuth_rad=0.0, highlight_elevation_rad=0.0
    )
    key = (choice.mode, repr(still))
    # (The mesh is compared by identity: ``loaded`` holds it, so its id cannot be reused.)
    if loaded is not None and loaded.get("key") == key and loaded.get("target") is target:
        places = studio_places(frame, r.elevation_rad, r.azimuth_rad, light, r.distance_scale)
        lamps = lamp_transforms(frame, places, light, r.distance_scale)
        renderer = loaded["renderer"]
        renderer.move_shapes({name: lamps[name] for name in ("softbox", "spot") if renderer.has(name)})
        converged, denoiser_name, object_pixels = _converge(None, design, fixed_spp, loaded)
    else:
        if loaded is not None:
            loaded.pop("renderer", None)
            loaded.pop("guides", None)
            loaded["key"] = key
            loaded["target"] = target
        converged, denoiser_name, object_pixels = load_and_converge(loaded)
    return Preview(
        converged.image,
        choice.mode,
        choice.reason,
        pixels,
        variant.variant,
        variant.warning,
        converged,
        denoiser_name,
        object_pixels,
    )


def _converge(
    scene_dict: dict[str, Any] | None,
    design: Design,
    fixed_spp: int | None,
    loaded: dict[str, Any] | None = None,
) -> tuple[Converged, str, int]:
    """Render ``scene_dict`` to the design's noise goal (or ``fixed_spp`` samples): the result, the
    denoiser's name (or why none), and the number of object pixels. ``loaded`` keeps the loaded
    scene and its denoiser guides for the next call (which then passes no ``scene_dict``)."""
    from printapp.denoiser import open_image_denoise
    from render.convergence import ConvergenceSettings, converge
    from render.progressive import SampleRenderer

    r = design.render
    if loaded is not None and "renderer" in loaded:
        renderer, guides = loaded["renderer"], loaded["guides"]
    else:
        assert scene_dict is not None
        renderer = SampleRenderer(scene_dict, r.width_px, r.height_px)
        guides = renderer.aovs(4, r.seed)
        if loaded is not None:
            loaded.update(renderer=renderer, guides=guides)
    mask = guides["coverage"] >= 0.5
    denoiser, denoiser_name = (None, 'off (design: [render] denoise = "off")')
    if r.denoise == "auto":
        denoiser, denoiser_name = open_image_denoise()
    first = max(1, (fixed_spp or r.spp) // 2)
    first = 1 << (first.bit_length() - 1)
    if fixed_spp is not None:
        settings = ConvergenceSettings(target=r.noise, first_spp=first, max_spp=2 * first, time_cap_s=1e9)
    else:
        settings = ConvergenceSettings(
            target=r.noise,
            first_spp=first,
            max_spp=max(r.max_spp, 2 * first),
            time_cap_s=r.time_cap_s,
            adaptive=r.sampling == "adaptive",
        )
    render, caustics = renderer.render, None
    if fixed_spp is None:
        # A coated relief's lamp caustics are light-traced, the rest path-traced (render.caustics):
        # on part_relief the same noise for two thirds of the time; and the camera's vertex is
        # done apart (render.coated_path): half the samples on the CAD parts.
        from render.caustics import preview_estimators

        estimators = preview_estimators(renderer, mask, r.seed)
        if estimators is not None:
            render, caustics = estimators
    result = converge(
        render,
        mask,
        seed=r.seed,
        settings=settings,
        denoiser=denoiser,
        guides=(guides["albedo"], guides["normal"]),
        denoiser_name=denoiser_name,
        caustics=caustics,
    )
    return result, denoiser_name, int(mask.sum())


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
    translucency: str = "medium",
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
                small,
                relief,
                mesh,
                predicted,
                appearance_field,
                medium=medium,
                light=light,
                tables=tables,
                fixed_spp=spp,
                translucency=translucency,
            ).image
        )
    return np.concatenate(strip, axis=1)


def highlight_frame(
    design: Design,
    relief: Relief,
    mesh: trimesh.Trimesh,
    predicted: Appearance,
    appearance_field: HeightField,
    *,
    medium: MediumRGB | None = None,
    tables: dict[str, TableSurface] | None = None,
    translucency: str = "medium",
) -> np.ndarray | None:
    """The verification frame of an anisotropic tile's highlight, lit by the mirror spot alone.

    The preview's camera and representation, small (:func:`printapp.highlight_check.frame_size`,
    :data:`printapp.highlight_check.FRAME_SPP` samples); None where the check does not apply
    (:func:`printapp.highlight_check.applies`).
    """
    from printapp.highlight_check import FRAME_SPP, applies, frame_size, spot_only

    if not applies(design, predicted.metrics)[0]:
        return None
    width, height = frame_size(design)
    small = design.model_copy(
        update={
            "render": design.render.model_copy(
                update={"width_px": width, "height_px": height, "spp": FRAME_SPP}
            )
        }
    )
    return render_preview(
        small,
        relief,
        mesh,
        predicted,
        appearance_field,
        medium=medium,
        light=spot_only(design),
        tables=tables,
        fixed_spp=FRAME_SPP,
        translucency=translucency,
    ).image


def parse_size(text: str) -> tuple[int, int]:
    """``"1024x768"`` to ``(1024, 768)``; else a :class:`printapp.errors.PrintappError` naming ``--size``."""
    from printapp.errors import PrintappError

    parts = text.lower().replace("×", "x").split("x")
    try:
        width, height = (int(p) for p in parts)
    except ValueError:
        raise PrintappError(
            f"--size: expected WIDTHxHEIGHT in pixels, such as 1024x768, got {text!r}"
        ) from None
    if not (16 <= width <= 4096 and 16 <= height <= 4096):
        raise PrintappError(f"--size: each side must be 16 to 4096 pixels, got {text!r}")
    return width, height


def render_design_file(
    design_file: Path,
    out: Path,
    *,
    mode: str | None = None,
    spp: int | None = None,
    distance_scale: float | None = None,
    size: tuple[int, int] | None = None,
    sweep: Path | None = None,
) -> tuple[Design, Preview, list[Path]]:
    """``printapp render``: path-trace a design's predicted appearance, and optionally a light sweep.

    ``mode``, ``spp``, ``distance_scale`` and ``size`` override the design's ``[render]`` table
    (None keeps the design's); the reason shown for the representation says which one asked
    for it. A named translucent material is rendered as ``printapp design`` renders it. Both
    images are written, or neither.
    """
    from printapp.design_io import load_design
    from printapp.errors import PrintappError
    from printapp.exporters import png_bytes
    from printapp.material_design import derive_design_material, render_choice
    from printapp.mesh import combine_solids
    from printapp.outputs import atomic_write_files
    from printapp.relief import appearance_field, build_relief
    from render.mitsuba_adapter import to_srgb8

    for path in (out, sweep):
        if path is not None and path.suffix.lower() != ".png":
            raise PrintappError(f"{path}: expected an image file ending in .png")
    design = load_design(design_file)
    source = "in the design" if "mode" in design.render.model_fields_set else "by default"
    updates: dict[str, Any] = {}
    if mode is not None:
        updates["mode"] = mode
        source = "with --mode"
    if spp is not None:
        updates["spp"] = spp
        updates["max_spp"] = max(spp, design.render.max_spp)
    if distance_scale is not None:
        updates["distance_scale"] = distance_scale
    if size is not None:
        updates["width_px"], updates["height_px"] = size
    design = design.model_copy(update={"render": design.render.model_copy(update=updates)})
    design, named = derive_design_material(design)
    relief = build_relief(design)
    mesh = combine_solids(relief.mesh, design.combine) if design.combine else relief.mesh
    medium, _, kind = render_choice(design, named, np.asarray(mesh.vertices))
    field, _ = appearance_field(design, relief)
    predicted = predict_for_design(design, field)
    preview = render_preview(
        design, relief, mesh, predicted, field, medium=medium, mode_source=source, translucency=kind
    )
    outputs = [(out, png_bytes(to_srgb8(preview.image)))]
    if sweep is not None:
        strip = light_sweep(design, relief, mesh, predicted, field, medium=medium, translucency=kind)
        outputs.append((sweep, png_bytes(to_srgb8(strip))))
    return design, preview, atomic_write_files(outputs)

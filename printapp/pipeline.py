"""Design to outputs: relief, printable mesh, checks, predicted appearance, preview, files.

Each stage is a pure function of the design (and its seed); files are staged and
moved into place only at the end.
"""

from __future__ import annotations

import json
import math
import platform
from dataclasses import dataclass, field
from importlib import metadata
from importlib.resources import as_file, files
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from noise.heightfield import HeightField
from printapp.brdf import brdf_arrays, npz_bytes
from printapp.design import Design, MeshBase, TileBase, load_design, resolved_toml
from printapp.exporters import OutputFolder, stl_bytes, threemf_bytes
from printapp.fields import is_tile_field, surface_lic_values
from printapp.mesh import (
    SolidCheck,
    check_solid,
    combine_solids,
    displace_along_normals,
    load_closed_mesh,
    refine_to_edge_length,
    slab_from_heightfield,
)
from printapp.progress import StageTimer
from printapp.texture import (
    evaluate_texture,
    evaluate_texture_grid,
    normalise_peak_to_valley,
    relief_heightfield,
)
from render.microfacet import SlopeRoughness, slope_roughness
from render.mitsuba_adapter import StudioLight
from slicing import Slices, slice_heightfield, slice_mesh, write_sl1
from slicing.printed import pixel_centres_mm, printed_heights

DEFAULT_DESIGN = files("printapp").joinpath("data/default_design.toml")
_PATCH_FEATURES = 12.0  # side of the flat patch used for appearance statistics, in base-octave features


@dataclass
class Relief:
    """The printable model and what was measured on it."""

    mesh: trimesh.Trimesh
    patch: HeightField
    """A flat patch of the relief, at the design's pitch and amplitude scale, for appearance."""
    undisplaced: trimesh.Trimesh | None = None
    """For mesh bases: the refined mesh before displacement (same faces as ``mesh``)."""
    softened_vertices: int = 0
    """For mesh bases: vertices whose relief was lowered so that no triangle folds."""


@dataclass
class Outcome:
    """The result of a design run."""

    manifest: dict[str, Any]
    written: list[Path]
    passed: bool
    reasons: list[str] = field(default_factory=list)
    render_warning: str | None = None


def build_relief(design: Design, base: trimesh.Trimesh | None = None) -> Relief:
    """The displaced, closed model of a design (mm) and a flat patch of its relief.

    ``base`` replaces loading the design's mesh file (e.g. a repaired mesh).
    """
    texture = design.texture
    pitch = design.pitch_mm
    if isinstance(design.base, TileBase):
        field_ = relief_heightfield(design)
        return Relief(mesh=slab_from_heightfield(field_, design.base.thickness_mm), patch=field_)
    assert isinstance(design.base, MeshBase)
    if base is None:
        base = load_closed_mesh(design.base.path, design.base.scale)
    if texture.kind == "lic":
        # The smeared noise varies on the scale of its features across the streamlines:
        # two vertices per feature resolve it.
        edge = max(texture.feature_size_mm / 2.0, pitch)
        refined = refine_to_edge_length(base, edge)
        raw = surface_lic_values(refined, texture, step_mm=pitch, base=base)
    else:
        # Four vertices per base-octave feature along an edge resolve the relief's shape;
        # finer than the printer's pixel is wasted.
        edge = max(texture.feature_size_mm / 4.0, pitch)
        refined = refine_to_edge_length(base, edge)
        raw = evaluate_texture(np.asarray(refined.vertices), texture, pitch_mm=edge)
    lo, hi = float(raw.min()), float(raw.max())
    mesh, softened = displace_along_normals(
        refined, normalise_peak_to_valley(raw, design.relief.amplitude_mm)
    )
    # A flat patch of the same texture on the mesh's value-to-height scale, so that its
    # slopes are the mesh's (for a mesh-only lic field, a constant field: the same slope
    # statistics up to a rotation).
    side = _PATCH_FEATURES * max(texture.feature_size_mm, texture.length_mm if texture.kind == "lic" else 0.0)
    n = max(3, min(1024, round(side / pitch) + 1))
    step = side / (n - 1)
    patch_texture = texture
    if texture.kind == "lic" and not is_tile_field(texture.field):
        patch_texture = texture.model_copy(update={"field": "constant:0"})
    values = evaluate_texture_grid(np.arange(n) * step, np.arange(n) * step, patch_texture, step)
    scale = design.relief.amplitude_mm / (hi - lo) if hi > lo else 0.0
    return Relief(
        mesh=mesh,
        patch=HeightField((values - lo) * scale, step, step),
        undisplaced=refined,
        softened_vertices=softened,
    )


@dataclass
class AsPrinted:
    """The printed relief of a tile (as a height field at the printer's pixels) and its error."""

    field: HeightField
    rms_error_mm: float
    max_error_mm: float


def as_printed(design_field: HeightField, slices: Slices, base_thickness_mm: float) -> AsPrinted:
    """What the printer makes of a tile: printed heights at pixel centres, against the design.

    The comparison uses pixels at least one pixel inside the tile's edges (the walls'
    grey pixels are not relief), the design interpolated bilinearly at the pixel centres.
    """
    from scipy.interpolate import RegularGridInterpolator

    heights = printed_heights(slices)
    x, y = pixel_centres_mm(slices)
    xd = x - slices.shift_mm[0] - design_field.origin_x_mm
    yd = y - slices.shift_mm[1] - design_field.origin_y_mm
    px, py = slices.profile.pitch_x_mm, slices.profile.pitch_y_mm
    cols = np.nonzero((xd > px) & (xd < design_field.width_mm - px))[0]
    rows = np.nonzero((yd > py) & (yd < design_field.depth_mm - py))[0]
    window = heights[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
    ny, nx = design_field.shape
    interpolate = RegularGridInterpolator(
        (np.arange(ny) * design_field.pitch_y_mm, np.arange(nx) * design_field.pitch_x_mm),
        design_field.heights_mm,
    )
    yy, xx = np.meshgrid(yd[rows], xd[cols], indexing="ij")
    designed = (
        interpolate(np.column_stack([yy.ravel(), xx.ravel()])).reshape(window.shape) + base_thickness_mm
    )
    error = window - designed
    return AsPrinted(
        field=HeightField(window - base_thickness_mm, px, py, float(xd[cols[0]]), float(yd[rows[0]])),
        rms_error_mm=float(np.sqrt(np.mean(error**2))),
        max_error_mm=float(np.max(np.abs(error))),
    )


def appearance_field(design: Design, relief: Relief | None = None) -> tuple[HeightField, str]:
    """The relief whose appearance a design predicts, and what it is.

    For a tile, what the printer makes of it (sliced and read back); for a mesh or a
    tile with booleans, a flat patch of the designed relief.
    """
    relief = relief or build_relief(design)
    if isinstance(design.base, TileBase) and not design.combine:
        slices = slice_tile(design, relief.patch)
        return as_printed(relief.patch, slices, design.base.thickness_mm).field, "as-printed relief"
    return relief.patch, "designed relief"


def slice_tile(design: Design, patch: HeightField) -> Slices:
    """A tile's layers straight from its height field: the same layers as slicing the slab, no mesh."""
    assert isinstance(design.base, TileBase)
    return slice_heightfield(
        patch,
        design.base.thickness_mm,
        design.printer.profile,
        layer_height_mm=design.layer_height_mm,
    )


def fits_printer(design: Design, solid: SolidCheck) -> bool:
    """Whether the model fits the printer's display and height, in either orientation."""
    profile = design.printer.profile
    sx, sy, sz = solid.size_mm
    w, d = profile.display_width_mm, profile.display_height_mm
    return ((sx <= w and sy <= d) or (sx <= d and sy <= w)) and sz <= profile.max_print_height_mm


def verify(
    design: Design,
    solid: SolidCheck,
    appearance: SlopeRoughness,
    image: np.ndarray | None,
    brdf_metrics: dict[str, Any] | None = None,
) -> tuple[list[str], list[str]]:
    """Printability and appearance checks: (passed descriptions, failure reasons)."""
    passed: list[str] = []
    failed: list[str] = []
    profile = design.printer.profile

    def check(ok: bool, good: str, bad: str) -> None:
        (passed if ok else failed).append(good if ok else bad)

    check(
        solid.ok,
        "mesh is closed, consistently oriented and manifold",
        f"mesh is not a valid solid (watertight={solid.watertight}, oriented={solid.winding_consistent}, "
        f"manifold3d: {solid.manifold_status})",
    )
    sx, sy, sz = solid.size_mm
    w, d = profile.display_width_mm, profile.display_height_mm
    check(
        fits_printer(design, solid),
        f"fits the {profile.label} build volume",
        f"model is {sx:.1f} x {sy:.1f} x {sz:.1f} mm; the {profile.label} prints at most "
        f"{w:g} x {d:g} x {profile.max_print_height_mm:g} mm",
    )
    lh = design.layer_height_mm
    check(
        design.relief.amplitude_mm >= lh,
        f"relief ({design.relief.amplitude_mm:g} mm) spans at least one layer ({lh:g} mm)",
        f"relief.amplitude_mm {design.relief.amplitude_mm:g} mm is less than one layer ({lh:g} mm): "
        "the relief would print flat",
    )
    two_px = 2.0 * profile.pitch_mm
    check(
        design.texture.feature_size_mm >= two_px,
        f"texture features ({design.texture.feature_size_mm:g} mm) span at least two pixels "
        f"({two_px:.3f} mm)",
        f"texture.feature_size_mm {design.texture.feature_size_mm:g} mm is below two printer pixels "
        f"({two_px:.3f} mm): the texture cannot be printed",
    )
    targets = design.appearance
    measures: list[tuple[str, Any, float, int]] = [
        ("roughness", targets.roughness, appearance.roughness, 3),
        ("anisotropy", targets.anisotropy, appearance.anisotropy, 2),
    ]
    if brdf_metrics is not None:
        gloss = brdf_metrics["gloss_gu"]
        measures += [
            ("gloss_20", targets.gloss_20, gloss["20"], 1),
            ("gloss_60", targets.gloss_60, gloss["60"], 1),
            ("gloss_85", targets.gloss_85, gloss["85"], 1),
            ("haze", targets.haze, brdf_metrics["haze"], 1),
            (
                "highlight_azimuth_deg",
                targets.highlight_azimuth_deg,
                brdf_metrics["highlight"]["azimuth_deg"],
                1,
            ),
        ]
    for name, target, value, digits in measures:
        if target is None:
            continue
        lo, hi = target
        miss = (lo - value) if value < lo else (value - hi)
        check(
            lo <= value <= hi,
            f"{name} {value:.{digits}f} is within [{lo:g}, {hi:g}]",
            f"{name} {value:.{digits}f} misses the target [{lo:g}, {hi:g}] by {miss:.{digits}f}",
        )
    if image is not None:
        finite = bool(np.all(np.isfinite(image)))
        check(
            finite and float(image.min()) >= 0.0 and float(image.std()) > 0.0,
            "preview render is finite, non-negative and not blank",
            "preview render has NaN, negative or constant pixels",
        )
        # Energy: a passive surface under the studio lights cannot outshine the brightest one.
        brightest = StudioLight().brightest
        check(
            finite and float(np.percentile(image, 99.9)) <= 1.05 * brightest,
            f"preview render is energy-plausible (no more than the brightest light's radiance {brightest:g})",
            f"preview render is brighter than its brightest light ({float(image.max()):.3g} > "
            f"{brightest:g}): the material returns more light than it receives",
        )
    return passed, failed


def _versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for name in (
        "printapp",
        "numpy",
        "numba",
        "scipy",
        "trimesh",
        "manifold3d",
        "mitsuba",
        "drjit",
        "pydantic",
    ):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def _finite_or_none(value: float) -> float | None:
    return None if not math.isfinite(value) else round(value, 6)


def run_design(
    design: Design,
    out_dir: str | Path,
    *,
    source: str = "design",
    force: bool = False,
    quiet: bool = False,
    render: bool = True,
) -> Outcome:
    """Run a design end to end and write its outputs into ``out_dir``.

    Writes ``model.stl``, ``model.3mf``, ``preview.png``, ``design.resolved.toml``,
    ``report.html`` and ``manifest.json``. When verification fails, the model files are written only with
    ``force``; everything else is written so that the user can see why.
    """
    from PIL import Image

    from printapp.rendering import light_sweep, predict_for_design, render_preview
    from printapp.report import png_bytes, report_html, sweep_settings
    from render.mitsuba_adapter import choose_variant, to_srgb8

    with OutputFolder(out_dir) as out, StageTimer(quiet=quiet) as timer:
        named_material = None
        if design.material.name is not None:
            from printapp.materials import derive_design_material, render_choice

            with timer.stage("material", "material optics (Lorenz-Mie)"):
                # Every later stage sees the index and body albedo derived from the particles.
                design, named_material = derive_design_material(design)
        with timer.stage("relief", "relief and printable mesh"):
            relief = build_relief(design)
            if design.combine:
                relief.mesh = combine_solids(relief.mesh, design.combine)
        mesh = relief.mesh
        with timer.stage("check", "solid checks (trimesh, manifold3d)"):
            solid = check_solid(mesh)
        slices = printed = None
        if solid.ok and fits_printer(design, solid):
            with timer.stage("slice", "slicing for the printer"):
                profile_ = design.printer.profile
                if isinstance(design.base, TileBase) and not design.combine:
                    slices = slice_tile(design, relief.patch)
                else:
                    slices = slice_mesh(
                        mesh.vertices, mesh.faces, profile_, layer_height_mm=design.layer_height_mm
                    )
            if isinstance(design.base, TileBase) and not design.combine:
                with timer.stage("as_printed", "as-printed relief"):
                    printed = as_printed(relief.patch, slices, design.base.thickness_mm)
        with timer.stage("appearance", "predicted appearance (slopes)"):
            # From what the printer will make where that is known, else from the design.
            sx, sy = (printed.field if printed is not None else relief.patch).slopes()
            appearance = slope_roughness(sx, sy)
        with timer.stage("brdf", "predicted BRDF (ray traced) and compact model"):
            brdf_field = printed.field if printed is not None else relief.patch
            predicted = predict_for_design(design, brdf_field)
        image = None
        choice = None
        preview = None
        sweep = None
        if render:
            with timer.stage("render", "path-traced preview (Mitsuba 3)"):
                choice = choose_variant()
                medium = None
                if named_material is not None:
                    medium, _ = render_choice(design, named_material, np.asarray(mesh.vertices))
                preview = render_preview(design, relief, mesh, predicted, brdf_field, medium=medium)
                image = preview.image
            with timer.stage("sweep", "light sweep for the report"):
                sweep = light_sweep(
                    design, relief, mesh, predicted, brdf_field, medium=medium, **sweep_settings(design)
                )
        with timer.stage("verify", "verification"):
            passed, failed = verify(design, solid, appearance, image, predicted.metrics)
            winding = slices.max_winding() if slices is not None else None
            if winding is not None:
                # Winding 1 inside a solid; 2 where the surface passes through itself. The
                # printer cures the union either way, so overlaps of less than half a pixel
                # are noted, not failed.
                if winding <= 1.01:
                    passed.append("the layers show no self-overlap (winding number 1)")
                elif winding < 1.5:
                    passed.append(
                        f"the surface overlaps itself by less than half a pixel somewhere (pixel-averaged "
                        f"winding number {winding:.2f}); the printer cures the union"
                    )
                else:
                    failed.append(
                        f"the model overlaps itself (winding number {winding:.2f} in some layer): "
                        "its surface passes through itself"
                    )
        ok = not failed
        with timer.stage("write", "writing outputs"):
            if image is not None:
                Image.fromarray(to_srgb8(image)).save(
                    out.path("preview.png"), optimize=False, compress_level=6
                )
            out.write_text("design.resolved.toml", resolved_toml(design))
            out.write_bytes("brdf.npz", npz_bytes(brdf_arrays(predicted)))
            if ok or force:
                out.write_bytes("model.stl", stl_bytes(mesh.vertices, mesh.faces))
                out.write_bytes("model.3mf", threemf_bytes(mesh.vertices, mesh.faces, design.name))
                if slices is not None:
                    with open(out.path("slices.sl1"), "wb") as stream:
                        write_sl1(stream, slices, "slices")
        profile = design.printer.profile
        lo, hi = solid.bbox_min_mm, solid.bbox_max_mm
        grid = list(relief.patch.shape) if isinstance(design.base, TileBase) else None
        manifest: dict[str, Any] = {
            "printapp": _versions()["printapp"],
            "versions": _versions(),
            "design": {"name": design.name, "source": source, "base": design.base.shape},
            "seeds": {
                "texture": design.texture.seed,
                "brdf": design.brdf.seed,
                "render": design.render.seed,
            },
            "stages_s": dict(timer.seconds),
            "triangles": solid.triangles,
            "vertices": int(len(mesh.vertices)),
            "watertight": solid.watertight,
            "winding_consistent": solid.winding_consistent,
            "manifold": solid.manifold,
            "genus": solid.genus,
            "volume_mm3": round(solid.volume_mm3, 6),
            "bbox_mm": {
                "min": [round(v, 6) for v in lo],
                "max": [round(v, 6) for v in hi],
                "size": [round(v, 6) for v in solid.size_mm],
            },
            "relief": {
                "amplitude_mm": design.relief.amplitude_mm,
                "pitch_mm": design.pitch_mm,
                "grid": grid,
                "sq_um": round(float(np.std(relief.patch.heights_mm)) * 1000.0, 4),
                "softened_vertices": relief.softened_vertices,
            },
            "printer": {
                "name": profile.name,
                "pixel_pitch_mm": profile.pitch_mm,
                "layer_height_mm": design.layer_height_mm,
                "layers": slices.n_layers
                if slices is not None
                else profile.layer_count(solid.size_mm[2], design.layer_height_mm),
                "antialias": profile.antialiasing,
            },
            "max_winding": None if winding is None else round(winding, 4),
            "as_printed": None
            if printed is None
            else {
                "model": "linear sub-voxel growth: a pixel of grey g cures g/255 of its layer",
                "rms_height_error_um": round(printed.rms_error_mm * 1000, 3),
                "max_height_error_um": round(printed.max_error_mm * 1000, 3),
                "grid": list(printed.field.shape),
            },
            "appearance": {
                "method": "relief slope statistics, Beckmann roughness (geometric optics)",
                "from": "as-printed relief" if printed is not None else "designed relief",
                "roughness": _finite_or_none(appearance.roughness),
                "anisotropy": _finite_or_none(appearance.anisotropy),
                "alpha_major": round(appearance.alpha_major, 6),
                "alpha_minor": round(appearance.alpha_minor, 6),
                "highlight_azimuth_deg": round(math.degrees(appearance.major_azimuth_rad), 3),
            },
            "brdf": {
                "method": "rays traced through the relief (Fresnel, all bounces, pigmented body); "
                "compact anisotropic microfacet model fitted to the table",
                "from": "as-printed relief" if printed is not None else "designed relief",
                **predicted.metrics,
            },
            "material": None
            if named_material is None
            else render_choice(design, named_material, np.asarray(mesh.vertices))[1],
            "render": None
            if image is None or choice is None
            else {
                "variant": choice.variant,
                "representation": preview.mode if preview is not None else None,
                "representation_reason": preview.reason if preview is not None else None,
                "relief_feature_pixels": round(preview.pixels_per_feature, 4)
                if preview is not None
                else None,
                "spp": design.render.spp,
                "size_px": [design.render.width_px, design.render.height_px],
                "mean_linear_rgb": [round(float(v), 6) for v in image.reshape(-1, 3).mean(axis=0)],
            },
            "verification": {
                "passed": ok,
                "checks": passed,
                "reasons": failed,
                "forced": bool(force and not ok),
            },
        }
        staged = [
            n
            for n in (
                "model.stl",
                "model.3mf",
                "slices.sl1",
                "preview.png",
                "brdf.npz",
                "design.resolved.toml",
            )
            if out.path(n).exists()
        ] + ["report.html"]
        manifest["outputs"] = [*staged, "manifest.json"]
        with timer.stage("report", "report (report.html)"):
            out.write_text(
                "report.html",
                report_html(
                    design,
                    manifest,
                    appearance=predicted,
                    preview_png=out.path("preview.png").read_bytes() if image is not None else None,
                    sweep_png=None if sweep is None else png_bytes(to_srgb8(sweep)),
                ),
            )
        manifest["stages_s"] = dict(timer.seconds)
        out.write_text("manifest.json", json.dumps(manifest, indent=2) + "\n")
        written = out.commit(staged + ["manifest.json"])
    return Outcome(
        manifest=manifest,
        written=written,
        passed=ok,
        reasons=failed,
        render_warning=None if choice is None else choice.warning,
    )


def load_default_design() -> Design:
    """The built-in design that ``printapp demo`` runs."""
    with as_file(DEFAULT_DESIGN) as path:
        return load_design(path)

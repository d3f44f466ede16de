"""Design to outputs: relief and printable mesh (:mod:`printapp.relief`), checks, predicted appearance,
preview, files.

Each stage is a pure function of the design (and its seed); files are staged and
moved into place only at the end.
"""

from __future__ import annotations

import functools
import json
import math
import platform
import time
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from printapp.background import Background
from printapp.brdf import brdf_arrays, npz_bytes
from printapp.cure import describe_constants
from printapp.design import Design, TileBase
from printapp.design_io import resolved_toml
from printapp.exporters import png_bytes, threemf_bytes, write_stl
from printapp.mesh import combine_solids, winding_verdict
from printapp.outputs import OutputFolder
from printapp.progress import StageTimer
from printapp.relief import (
    as_printed,
    build_relief,
    cure_model,
    cure_spread,
    fits_printer,
    fits_printer_size,
    slice_tile,
)
from printapp.solid import SolidCheck, check_solid
from render.microfacet import SlopeRoughness, slope_roughness
from render.mitsuba_adapter import StudioLight
from slicing import Slices, slice_mesh, write_sl1

T = TypeVar("T")

DESIGN_OUTPUTS = (
    "model.stl",
    "model.3mf",
    "slices.sl1",
    "preview.png",
    "brdf.npz",
    "design.resolved.toml",
    "report.html",
    "manifest.json",
)
"""Every file a design run may write into its folder, in the order the manifest lists them."""


@dataclass
class Outcome:
    """The result of a design run."""

    manifest: dict[str, Any]
    written: list[Path]
    passed: bool
    reasons: list[str] = field(default_factory=list)
    render_warning: str | None = None


def verify(
    design: Design,
    solid: SolidCheck,
    appearance: SlopeRoughness,
    image: np.ndarray | None,
    brdf_metrics: dict[str, Any] | None = None,
    preview_noise: tuple[bool, str] | None = None,
) -> tuple[list[str], list[str]]:
    """Printability and appearance checks: (passed descriptions, failure reasons).

    ``preview_noise`` is :func:`printapp.rendering.noise_summary` of the preview: whether its
    raw (un-denoised) noise met its threshold, and the sentence that says so or why not.
    """
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
        if value is None:
            reason = (brdf_metrics or {}).get(f"{name}_reason", "n/a")
            failed.append(f"{name} cannot be checked against the target [{lo:g}, {hi:g}]: {reason}")
            continue
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
    if preview_noise is not None:
        ok, sentence = preview_noise
        check(ok, sentence, sentence)
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


STAGES = (
    "material",
    "relief",
    "check",
    "slice",
    "winding",
    "as_printed",
    "appearance",
    "brdf",
    "render",
    "brdf_analytic",
    "report_figure",
    "write_model",
    "sweep",
    "highlight",
    "verify",
    "write",
    "report",
)
"""A design run's stages in the order the manifest lists them (the background ones, timed on
their own thread, in the order they are started), whatever order they finish in."""


def _stage_order(seconds: dict[str, float]) -> dict[str, float]:
    return {name: seconds[name] for name in STAGES if name in seconds}


MODEL_OUTPUTS = ("model.stl", "model.3mf", "slices.sl1")


def _write_models(
    out: OutputFolder,
    timer: StageTimer,
    design: Design,
    mesh: Any,
    checked: Future[tuple[SolidCheck, Slices | None, float | None]],
    tile_slices: Slices | None,
) -> list[str]:
    """Stage the model files (before the verdict, in the background); the names staged."""
    _, mesh_slices, _ = checked.result()
    slices = tile_slices if tile_slices is not None else mesh_slices
    with timer.stage("write_model", "writing the model and slices", background=True):
        out.write_bytes("model.stl", functools.partial(write_stl, vertices=mesh.vertices, faces=mesh.faces))
        out.write_bytes("model.3mf", threemf_bytes(mesh.vertices, mesh.faces, design.name))
        if slices is None:
            return list(MODEL_OUTPUTS[:2])
        out.write_bytes("slices.sl1", functools.partial(write_sl1, slices=slices, job_name="slices"))
    return list(MODEL_OUTPUTS)


def _staged(timer: StageTimer, name: str, label: str, fn: Callable[[], T]) -> T:
    """``fn()`` timed as the background stage ``name``."""
    with timer.stage(name, label, background=True):
        return fn()


def _analytic_fit(timer: StageTimer, design: Design, predicted: Any) -> Any:
    from printapp.rendering import analytic_for_design

    with timer.stage("brdf_analytic", "analytic BRDF fit beside the compact model", background=True):
        return analytic_for_design(design, predicted)


def _brdf_figure(timer: StageTimer, predicted: Any) -> bytes:
    from printapp.report_figures import brdf_figure_png

    with timer.stage("report_figure", "BRDF maps for the report", background=True):
        return brdf_figure_png(predicted)


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

    from printapp.highlight_check import check_highlight
    from printapp.rendering import (
        highlight_frame,
        light_sweep,
        noise_record,
        noise_summary,
        predict_for_design,
        render_preview,
    )
    from printapp.report import report_html, sweep_settings
    from render.mitsuba_adapter import choose_variant, to_srgb8

    with (
        OutputFolder(out_dir, owned=DESIGN_OUTPUTS.__contains__) as out,
        StageTimer(quiet=quiet) as timer,
        Background() as background,
    ):
        began = time.perf_counter()
        named_material = None
        if design.material.name is not None:
            from printapp.material_design import derive_design_material, render_choice

            with timer.stage("material", "material optics (Lorenz-Mie)"):
                # Every later stage sees the index and body albedo derived from the particles.
                design, named_material = derive_design_material(design)
        with timer.stage("relief", "relief and printable mesh"):
            relief = build_relief(design)
            if design.combine:
                relief.mesh = combine_solids(relief.mesh, design.combine)
        mesh = relief.mesh
        tile = isinstance(design.base, TileBase) and not design.combine
        size_mm = np.ptp(np.asarray(mesh.vertices), axis=0)
        fits = fits_printer_size(design, (float(size_mm[0]), float(size_mm[1]), float(size_mm[2])))

        def check_and_slice() -> tuple[SolidCheck, Slices | None, float | None]:
            with timer.stage("check", "solid checks (edge count, manifold3d)", background=True):
                solid = check_solid(mesh)
            if tile or not (solid.ok and fits):
                return solid, None, None
            with timer.stage("slice", "slicing for the printer", background=True):
                sliced = slice_mesh(
                    mesh.vertices, mesh.faces, design.printer.profile, layer_height_mm=design.layer_height_mm
                )
            with timer.stage("winding", "the layers' winding numbers", background=True):
                return solid, sliced, sliced.max_winding()

        # Off the critical path, from now on: the checks, and a mesh's slicing.
        checked = background.submit(check_and_slice)
        slices = printed = None
        if tile and fits:
            # A tile's layers come from its height field, not from the mesh the checks look at.
            with timer.stage("slice", "slicing for the printer"):
                slices = slice_tile(design, relief.patch)
            with timer.stage("as_printed", "as-printed relief"):
                printed = as_printed(
                    relief.patch,
                    slices,
                    design.base.thickness_mm,
                    cure_model(design),
                    cure_spread(design)[0],
                )
        tile_winding = (
            background.submit(_staged, timer, "winding", "the layers' winding numbers", slices.max_winding)
            if slices is not None
            else None
        )

        def write_models() -> Future[list[str]]:
            return background.submit(_write_models, out, timer, design, mesh, checked, slices)

        # The model files are staged once the preview has met its noise goal (what most often
        # fails a run), beside the light sweep; unstaged again if anything else fails. The
        # checks and a mesh's slicing run beside the BRDF (they are usually done before the
        # preview starts).
        models = None if render else write_models()
        with timer.stage("appearance", "predicted appearance (slopes)"):
            # From what the printer will make where that is known, else from the design.
            sx, sy = (printed.field if printed is not None else relief.patch).slopes()
            appearance = slope_roughness(sx, sy)
        with timer.stage("brdf", "predicted BRDF (ray traced) and compact model"):
            brdf_field = printed.field if printed is not None else relief.patch
            predicted = predict_for_design(design, brdf_field, analytic=False)
        image = None
        choice = None
        preview = None
        sweep = None
        frame = None
        if render:
            with timer.stage("render", "path-traced preview (Mitsuba 3)"):
                choice = choose_variant()
                medium, kind = None, "albedo"
                if named_material is not None:
                    medium, _, kind = render_choice(design, named_material, np.asarray(mesh.vertices))
                preview = render_preview(
                    design, relief, mesh, predicted, brdf_field, medium=medium, translucency=kind
                )
                image = preview.image
        # After the preview, not beside it: its rounds' timing sets the time cap's budget. The
        # analytic fit beside the compact model is for the files and the report only.
        fitted = background.submit(_analytic_fit, timer, design, predicted)
        brdf_png = background.submit(_brdf_figure, timer, predicted)
        if render and (force or (preview is not None and noise_summary(preview)[0])):
            models = write_models()
        if render:
            with timer.stage("sweep", "light sweep for the report"):
                sweep = light_sweep(
                    design,
                    relief,
                    mesh,
                    predicted,
                    brdf_field,
                    medium=medium,
                    translucency=kind,
                    **sweep_settings(design),
                )
            with timer.stage("highlight", "highlight frame (anisotropic tiles)"):
                frame = highlight_frame(
                    design, relief, mesh, predicted, brdf_field, medium=medium, translucency=kind
                )
        solid, mesh_slices, mesh_winding = checked.result()
        predicted = fitted.result()
        slices = slices if tile else mesh_slices
        winding = tile_winding.result() if tile_winding is not None else mesh_winding
        with timer.stage("verify", "verification"):
            passed, failed = verify(
                design,
                solid,
                appearance,
                image,
                predicted.metrics,
                preview_noise=None if preview is None else noise_summary(preview),
            )
            if winding is not None:
                overlap = winding_verdict(winding)
                (passed if overlap.ok else failed).append(overlap.message)
            highlight = check_highlight(design, relief, mesh, predicted.metrics, frame)
            if highlight.applied:
                (passed if highlight.ok else failed).append(highlight.sentence)
        ok = not failed
        if models is None and (ok or force):
            models = write_models()  # (a run whose preview missed its goal, forced)
        written_models = models.result() if models is not None else []
        if not (ok or force):
            for name in written_models:
                out.discard(name)
        with timer.stage("write", "writing outputs"):
            if image is not None:
                out.write_bytes("preview.png", png_bytes(to_srgb8(image)))
            out.write_text("design.resolved.toml", resolved_toml(design))
            out.write_bytes("brdf.npz", npz_bytes(brdf_arrays(predicted)))
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
            "stages_s": _stage_order(timer.seconds),
            "stages_in_background": [name for name in STAGES if name in timer.background],
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
                "frame": relief.frame.as_dict() if relief.frame is not None else None,
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
                "model": cure_model(design).describe(),
                "cure": describe_constants(cure_model(design)),
                "cure_spread_um": round(cure_spread(design)[0] * 1000.0, 4),
                "cure_spread_source": cure_spread(design)[1],
                "exposure": "grey levels from the relief's heights"
                if design.relief.grey_levels
                else "binary pixels from the relief's heights"
                if design.relief.pixel_texture_mm > 0
                else "anti-aliased area coverage (PrusaSlicer)",
                "pixel_texture_um": round(design.relief.pixel_texture_mm * 1000.0, 6),
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
                "compact microfacet model of the relief's own facet normals (tabulated NDF, Smith masking, "
                "second-bounce compensation, facet-local body), compared with the table; an analytic "
                "GGX/Beckmann fit beside it",
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
                "spp": None if preview is None or preview.convergence is None else preview.convergence.spp,
                "first_spp": design.render.spp,
                "size_px": [design.render.width_px, design.render.height_px],
                "noise": None if preview is None else noise_record(preview),
                "mean_linear_rgb": [round(float(v), 6) for v in image.reshape(-1, 3).mean(axis=0)],
            },
            "highlight_check": None if not render else highlight.record,
            "verification": {
                "passed": ok,
                "checks": passed,
                "reasons": failed,
                "forced": bool(force and not ok),
            },
        }
        staged = [n for n in DESIGN_OUTPUTS[:-2] if out.path(n).exists()] + ["report.html"]
        manifest["outputs"] = [*staged, "manifest.json"]
        manifest["wall_s"] = round(time.perf_counter() - began, 4)  # (so far: the report shows it)
        with timer.stage("report", "report (report.html)"):
            out.write_text(
                "report.html",
                report_html(
                    design,
                    manifest,
                    appearance=predicted,
                    brdf_png=brdf_png.result(),
                    preview_png=out.path("preview.png").read_bytes() if image is not None else None,
                    sweep_png=None if sweep is None else png_bytes(to_srgb8(sweep)),
                    highlight_png=None if frame is None else png_bytes(to_srgb8(frame)),
                ),
            )
        manifest["stages_s"] = _stage_order(timer.seconds)
        manifest["wall_s"] = round(time.perf_counter() - began, 4)
        out.write_text("manifest.json", json.dumps(manifest, indent=2) + "\n")
        written = sorted(out.commit(), key=lambda path: DESIGN_OUTPUTS.index(path.name))
    return Outcome(
        manifest=manifest,
        written=written,
        passed=ok,
        reasons=failed,
        render_warning=None if choice is None else choice.warning,
    )

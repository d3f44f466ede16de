"""``printapp brdf`` and ``printapp render``: predicted appearance and path-traced previews."""

from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer

from printapp.cli.app import QuietOption, app, out, percent, warn, working, wrote


class FitDistribution(StrEnum):
    auto = "auto"
    ggx = "ggx"
    beckmann = "beckmann"


@app.command()
def brdf(
    source: Annotated[
        Path,
        typer.Argument(
            help="A design (.toml), a height map (.npy .png .tif .al3d .x3p .gwy) or a mesh tile."
        ),
    ],
    out_path: Annotated[Path, typer.Option("--out", "-o", help="The table to write (.npz).")] = Path(
        "brdf.npz"
    ),
    plot: Annotated[Path | None, typer.Option(help="Draw the table and the fit (.png).")] = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the appearance metrics (.json).")
    ] = None,
    ior: Annotated[
        float | None, typer.Option(help="Refractive index of the resin [design's, else 1.5].")
    ] = None,
    body_albedo: Annotated[
        float | None, typer.Option(help="Albedo of the pigmented body [design's luminance, else 0.8].")
    ] = None,
    incident_deg: Annotated[
        str | None, typer.Option(help="Incident directions 'THETA:PHI,...' in degrees [a sweep of 7].")
    ] = None,
    rays: Annotated[
        int,
        typer.Option(min=100, max=100_000_000, help="Primary rays per direction (--lobe-error: first run)."),
    ] = 200_000,
    lobe_error: Annotated[
        float | None,
        typer.Option(
            help="Trace each direction until its reflection lobe's relative standard error is this "
            "(e.g. 0.01) [design's, else off]."
        ),
    ] = None,
    max_rays: Annotated[
        int, typer.Option(min=100, max=1_000_000_000, help="With --lobe-error: most rays per direction.")
    ] = 100_000_000,
    theta_bins: Annotated[int, typer.Option(min=4, max=360, help="Outgoing bins over 0-90 deg.")] = 45,
    phi_bins: Annotated[int, typer.Option(min=4, max=720, help="Outgoing bins over 0-360 deg.")] = 90,
    distribution: Annotated[FitDistribution, typer.Option(help="Fitted microfacet distribution.")] = (
        FitDistribution.auto
    ),
    seed: Annotated[
        int | None, typer.Option(min=0, help="Seed of the rays [the design's [brdf] seed, else 0].")
    ] = None,
    periodic: Annotated[
        bool, typer.Option(help="The map tiles seamlessly (else only its interior is lit).")
    ] = False,
    width_mm: Annotated[float | None, typer.Option(help="Images: physical width (mm).")] = None,
    depth_mm: Annotated[
        float | None, typer.Option(help="Images: relief depth, white minus black (mm).")
    ] = None,
    pitch_mm: Annotated[
        float | None, typer.Option(help=".npy: sample spacing (mm); meshes: sampling pitch [median edge].")
    ] = None,
    flatten: Annotated[
        str | None, typer.Option(help="Height maps: level first, 'plane' or 'poly:K'.")
    ] = None,
    quiet: QuietOption = False,
) -> None:
    """Predict the BRDF of a printed surface by tracing rays through its microgeometry.

    Writes the bin-averaged table (brdf.npz), and optionally a plot and the appearance
    metrics: albedo, gloss at 20/60/85 deg (ISO 2813), haze (ASTM D4039, high-gloss
    surfaces only), the highlight's anisotropy, and the compact microfacet model of the
    relief's own facets with its error (a warning where the traced table must stand in).
    """
    from printapp.brdf import predict_file

    with working("tracing the BRDF and fitting the model", quiet):
        result = predict_file(
            source,
            out_path,
            plot=plot,
            json_out=json_out,
            ior=ior,
            body_albedo=body_albedo,
            incident_deg=incident_deg,
            rays=rays,
            lobe_error=lobe_error,
            max_rays=max_rays,
            theta_bins=theta_bins,
            phi_bins=phi_bins,
            distribution=distribution.value,
            seed=seed,
            periodic=periodic,
            width_mm=width_mm,
            depth_mm=depth_mm,
            pitch_mm=pitch_mm,
            flatten=flatten,
        )
    m = result.predicted.metrics
    fit, hl = m["fit"], m["highlight"]
    ny, nx = result.field.shape
    haze = f"haze {m['haze']:.1f}" if m["haze"] is not None else f"haze {m['haze_reason']}"
    out.print(
        f"{source.name} ({result.origin}, {nx} x {ny} samples): albedo "
        f"{m['albedo'][0]:.3f} at normal incidence; gloss {m['gloss_gu']['20']:.1f} / "
        f"{m['gloss_gu']['60']:.1f} / {m['gloss_gu']['85']:.1f} GU at 20/60/85 deg, {haze}; "
        f"highlight anisotropy {hl['anisotropy']:.2f} along {hl['azimuth_deg']:.0f} deg"
    )
    spike = f", {fit['spike_weight']:.0%} of it flat (a mirror spike)" if fit["spike_weight"] > 0 else ""
    out.print(
        f"compact model: the relief's own facet normals, tabulated (slope roughness {fit['alpha_u']:.3g} x "
        f"{fit['alpha_v']:.3g} along {fit['azimuth_deg']:.0f} deg{spike}), body albedo "
        f"{fit['body_albedo']:.3f}; relative error {percent(fit['relative_error'])} over {fit['bins']} bins "
        f"(the table's own noise there: {percent(fit['table_noise'])}); {m['representation']['reason']}"
    )
    a = m["fit_analytic"]
    a_spike = f", {a['spike_weight']:.0%} in a mirror spike" if a["spike_weight"] > 0 else ""
    out.print(
        f"analytic fit, for comparison: {a['distribution']} alpha {a['alpha_u']:.3g} x "
        f"{a['alpha_v']:.3g} along "
        f"{a['azimuth_deg']:.0f} deg{a_spike}; relative error {percent(a['relative_error'])}"
    )
    for line in m["warnings"]:
        warn(line)
    errors = ", ".join(percent(e) for e in m["lobe_error"])
    rays_used = m["rays_per_direction"]
    low, high = min(rays_used), max(rays_used)
    budget = f"{low:,}" if low == high else f"{low:,} to {high:,}"
    out.print(f"reflection lobe's standard error per direction: {errors} ({budget} rays per direction)")
    wrote(result.written)


class RenderMode(StrEnum):
    auto = "auto"
    model = "model"
    table = "table"
    geometry = "geometry"


@app.command()
def render(
    design_file: Annotated[Path, typer.Argument(help="Design file (TOML).")],
    out_path: Annotated[Path, typer.Option("--out", "-o", help="The image to write (.png).")] = Path(
        "render.png"
    ),
    spp: Annotated[
        int | None, typer.Option(min=1, max=65536, help="Samples per pixel of the first passes [design's].")
    ] = None,
    mode: Annotated[
        RenderMode | None,
        typer.Option(help="Relief as its fitted BRDF, its traced table, or geometry [design's, else auto]."),
    ] = None,
    size: Annotated[
        str | None, typer.Option(help="Image size WIDTHxHEIGHT in pixels [design's, else 1024x768].")
    ] = None,
    distance_scale: Annotated[
        float | None, typer.Option(min=0.2, max=1000.0, help="Camera distance, 1 = framing [design's].")
    ] = None,
    sweep: Annotated[
        Path | None, typer.Option(help="Also write a light-sweep strip (.png): the light circles the object.")
    ] = None,
    quiet: QuietOption = False,
) -> None:
    """Path-trace a design's predicted appearance, with the representation the camera needs.

    Passes are added until the noise of the object's pixels meets the design's [render] noise
    (2 % by default), or its sample budget or time cap is spent.
    """
    from printapp.rendering import noise_summary, parse_size, render_design_file

    with working("path tracing (Mitsuba 3)", quiet):
        design, preview, written = render_design_file(
            design_file,
            out_path,
            mode=None if mode is None else mode.value,
            spp=spp,
            distance_scale=distance_scale,
            size=None if size is None else parse_size(size),
            sweep=sweep,
        )
    if preview.warning:
        warn(preview.warning)
    out.print(f"{design.name}: rendered as {preview.mode} ({preview.reason}) on {preview.variant}")
    converged, line = noise_summary(preview)
    (out.print if converged else warn)(line)
    wrote(written)

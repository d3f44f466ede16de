"""``report.html``: one self-contained page that tells a designer what ``printapp design`` made.

Everything is inline (CSS, and every image as a base64 PNG data URI), nothing is fetched
from the network and nothing runs: the page reads the same offline, attached to an e-mail
or opened years later. Every piece of text that comes from a design or a run is escaped.
"""

from __future__ import annotations

import base64
import html
import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

from printapp.design import Design
from printapp.design_io import resolved_toml
from printapp.report_figures import brdf_figure_png
from printapp.texture_kinds import texture_kind

SWEEP_FRAMES = 6
SWEEP_SIZE_PX = (160, 120)
SWEEP_SPP = 8

# (metric, where in the manifest, decimals shown, unit, what it means)
_METRICS: tuple[tuple[str, tuple[str, ...], int, str, str], ...] = (
    (
        "roughness",
        ("appearance", "roughness"),
        3,
        "",
        "Beckmann roughness of the relief's slopes (0: mirror-smooth; above 0.3: matte)",
    ),
    (
        "anisotropy",
        ("appearance", "anisotropy"),
        2,
        "",
        "ratio of the larger to the smaller roughness (1: the same in every direction)",
    ),
    ("gloss_20", ("brdf", "gloss_gu", "20"), 1, "GU", "glossmeter reading at 20 degrees (high gloss)"),
    ("gloss_60", ("brdf", "gloss_gu", "60"), 1, "GU", "glossmeter reading at 60 degrees (the usual one)"),
    ("gloss_85", ("brdf", "gloss_gu", "85"), 1, "GU", "glossmeter reading at 85 degrees (sheen)"),
    (
        "haze",
        ("brdf", "haze"),
        1,
        "GU",
        "haze index G60 - G20 (ASTM D4039, high-gloss surfaces only): light scattered just off the "
        "mirror direction",
    ),
)

_STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", Helvetica, Arial, sans-serif; margin: 0;
       background: #f4f4f1; color: #1d1d1b; line-height: 1.45; }
main { max-width: 1100px; margin: 0 auto; padding: 1.5em 2em 3em; background: #fff; }
h1 { font-size: 1.7em; margin-bottom: 0.2em; }
h2 { font-size: 1.25em; margin-top: 1.8em; border-bottom: 1px solid #ddd; padding-bottom: 0.2em; }
p.explain { color: #444; max-width: 60em; }
.verdict { padding: 0.8em 1.1em; border-radius: 6px; margin: 1em 0; }
.verdict.pass { background: #e3f3e3; border: 1px solid #7bbf7b; }
.verdict.fail { background: #fbe3e1; border: 1px solid #d9776d; }
table { border-collapse: collapse; margin: 0.6em 0; }
th, td { border: 1px solid #d6d6d2; padding: 0.25em 0.6em; text-align: left; vertical-align: top; }
th { background: #efefeb; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
td.pass { color: #1f6f1f; font-weight: 600; }
td.miss { color: #a52a1f; font-weight: 600; }
td.none { color: #777; }
pre { background: #f6f6f3; border: 1px solid #ddd; padding: 0.7em; overflow: auto; font-size: 0.85em;
      max-height: 28em; }
img { max-width: 100%; height: auto; border: 1px solid #ccc; }
img.pixels { image-rendering: pixelated; min-width: 320px; }
.bar { background: #8aa9c9; height: 0.8em; display: inline-block; }
nav a { margin-right: 0.9em; }
ul.checks li { margin: 0.15em 0; }
"""


def _e(value: Any) -> str:
    return html.escape(str(value), quote=True)


def _data_uri(png: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def sweep_settings(design: Design) -> dict[str, int]:
    """Frame size and samples of the report's light sweep: small, and never larger than the preview.

    Returns the keyword arguments of :func:`printapp.rendering.light_sweep`
    (``frames``, ``width_px``, ``height_px``, ``spp``); frames keep the preview's aspect.
    A design that asks for many samples per pixel needs them (a translucent resin's light
    wanders far: at 8 samples its frames are speckle), so the sweep takes an eighth of
    the preview's samples when that is more than :data:`SWEEP_SPP`.
    """
    r = design.render
    width = min(SWEEP_SIZE_PX[0], r.width_px)
    height = min(SWEEP_SIZE_PX[1], max(16, round(width * r.height_px / r.width_px)))
    spp = min(r.spp, max(SWEEP_SPP, r.spp // 8))
    return {"frames": SWEEP_FRAMES, "width_px": width, "height_px": height, "spp": spp}


def _samples_text(spp: Any, noise: Mapping[str, Any] | None) -> Any:
    """The preview's samples per pixel: their mean over the object, and their range where they varied."""
    low, high = (noise or {}).get("spp_range") or (spp, spp)
    if spp is None or low == high:
        return spp
    return f"{spp} on average over the object, from {low} to {high} (more where the noise is)"


def _noise_rows(noise: Mapping[str, Any] | None) -> list[tuple[str, Any]]:
    """The preview's noise as the report shows it: raw figure, goal, denoiser, why it stopped."""
    if not noise:
        return []
    rows: list[tuple[str, Any]] = [
        (
            "noise (raw, un-denoised)",
            f"{noise['raw_relative_noise']:.2%} of the object's mean luminance "
            f"(at most {noise['target']:.0%}; {noise['object_pixels']:,} object pixels)",
        ),
        ("converged", "yes" if noise["converged"] else f"no: stopped by the {noise['stopped_by']}"),
    ]
    if noise["denoised"]:
        rows.append(
            (
                "denoised",
                f"yes, the image shown is denoised by {noise['denoiser']}; its error against a converged "
                f"render, estimated from the independent halves: {noise['denoised_error']:.2%} (the "
                "verdict reads the raw noise)",
            )
        )
    else:
        rows.append(("denoised", f"no (denoiser: {noise['denoiser']})"))
    return rows


def _lookup(manifest: Mapping[str, Any], path: tuple[str, ...]) -> Any:
    node: Any = manifest
    for key in path:
        if not isinstance(node, Mapping) or key not in node:
            return None
        node = node[key]
    return node


def metric_rows(design: Design, manifest: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The appearance metrics against the design's targets.

    Each row: ``metric``, ``value`` (None when not predicted), ``target`` ([lo, hi] or
    None), ``verdict`` ("pass", "miss", "no target" or "not predicted"), ``miss`` (by how
    much the value lies outside the range, in the metric's units; 0 when inside),
    ``digits``, ``unit`` and ``meaning``. The verdicts are those of
    :func:`printapp.pipeline.verify`, which ``manifest["verification"]`` records.
    """
    rows = []
    for name, path, digits, unit, meaning in _METRICS:
        value = _lookup(manifest, path)
        target = getattr(design.appearance, name)
        miss = 0.0
        if value is None:
            verdict = "not predicted"
            reason = _lookup(manifest, (*path[:-1], f"{path[-1]}_reason"))
            if isinstance(reason, str) and reason.startswith("n/a"):
                verdict = reason
                if target is not None:
                    verdict += "; the target cannot be checked"
        elif target is None:
            verdict = "no target"
        else:
            lo, hi = target
            miss = (lo - value) if value < lo else (value - hi) if value > hi else 0.0
            verdict = "pass" if lo <= value <= hi else "miss"
        rows.append(
            {
                "metric": name,
                "value": value,
                "target": None if target is None else [float(target[0]), float(target[1])],
                "verdict": verdict,
                "miss": float(miss),
                "digits": digits,
                "unit": unit,
                "meaning": meaning,
            }
        )
    return rows


def _kv_table(rows: Sequence[tuple[str, Any]]) -> str:
    body = "".join(f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>" for k, v in rows)
    return f"<table>{body}</table>"


def _rays_text(rays: Any) -> str:
    """One count when every direction had the same rays, else the list."""
    if isinstance(rays, list) and rays:
        return f"{rays[0]:,}" if len(set(rays)) == 1 else ", ".join(f"{r:,}" for r in rays)
    return "n/a" if rays is None else f"{rays:,}"


def _percent_list(values: Any) -> str:
    if not values:
        return "n/a"
    return ", ".join("n/a" if v is None else f"{100.0 * v:.1f} %" for v in values)


def _fmt_mm(values: Sequence[float]) -> str:
    return " x ".join(f"{v:.3f}" for v in values) + " mm"


def _image(png: bytes | None, alt: str, missing: str, pixels: bool = False) -> str:
    if png is None:
        return f"<p><em>{_e(missing)}</em></p>"
    css = ' class="pixels"' if pixels else ""
    return f'<p><img{css} src="{_data_uri(png)}" alt="{_e(alt)}"></p>'


def _brdf_rows(b: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """The BRDF section's table: the compact model, its error, the analytic fit, what renders."""
    fit = b.get("fit") or {}
    analytic = b.get("fit_analytic") or {}
    use = b.get("representation") or {}

    def pct(value: Any) -> str:
        return "n/a (too few rays)" if value is None else f"{100.0 * value:.1f} %"

    nan = float("nan")
    spike = fit.get("spike_weight") or 0.0
    rows: list[tuple[str, Any]] = [
        (
            "compact model",
            "microfacets with the relief's own distribution of facet normals (tabulated), Smith masking "
            "from it, second-bounce compensation, the body lit facet by facet"
            + (f"; {spike:.0%} of the surface flat (a mirror spike)" if spike > 0 else ""),
        ),
        (
            "slope roughness alpha_u, alpha_v",
            f"{fit.get('alpha_u', nan):.4f}, {fit.get('alpha_v', nan):.4f} along "
            f"{fit.get('azimuth_deg', nan):.1f}°",
        ),
        ("body albedo", f"{fit.get('body_albedo', nan):.3f}"),
        ("compact model's relative error", pct(fit.get("relative_error"))),
        ("the table's own noise on those bins", pct(fit.get("table_noise"))),
    ]
    if use:
        rows.append(("rendered with", f"the {use.get('use')}: {use.get('reason')}"))
    if analytic:
        rows.append(
            (
                "analytic fit, for comparison",
                f"{analytic.get('distribution')} alpha {analytic.get('alpha_u', nan):.4f} x "
                f"{analytic.get('alpha_v', nan):.4f}, relative error {pct(analytic.get('relative_error'))}",
            )
        )
    haze = b.get("haze_reason")
    if haze:
        rows.append(("haze", haze if b.get("haze") is None else f"{b['haze']:.1f} GU: {haze}"))
    rows += [
        ("rays per incident direction", _rays_text(b.get("rays_per_direction"))),
        ("lobe standard error per direction", _percent_list(b.get("lobe_error"))),
        ("traced from", b.get("from")),
    ]
    return rows


def _verdict_section(manifest: Mapping[str, Any]) -> str:
    v = manifest.get("verification") or {}
    reasons = list(v.get("reasons", []))
    if v.get("passed"):
        head = "Verified: every check passed, and all outputs were written."
        cls = "pass"
    else:
        written = (
            "The model was written anyway (--force)."
            if v.get("forced")
            else "No printable model was written; rerun with --force to write it anyway."
        )
        head = f"Failed verification: {len(reasons)} check(s) missed. {written}"
        cls = "fail"
    items = "".join(f"<li>{_e(r)}</li>" for r in reasons)
    return (
        f'<div class="verdict {cls}"><strong>{_e(head)}</strong>'
        + (f"<ul>{items}</ul>" if items else "")
        + "</div>"
    )


def report_html(
    design: Design,
    manifest: Mapping[str, Any],
    *,
    appearance: Any = None,
    brdf_png: bytes | None = None,
    preview_png: bytes | None = None,
    sweep_png: bytes | None = None,
    sweep_frames: int = SWEEP_FRAMES,
    highlight_png: bytes | None = None,
) -> str:
    """The report of one design run as a self-contained HTML page.

    Parameters
    ----------
    design : Design
        The design as run (its resolved TOML is shown; its ``[appearance]`` holds the targets).
    manifest : mapping
        The run's ``manifest.json`` content (:func:`printapp.pipeline.run_design`).
    appearance : render.appearance.Appearance, optional
        The predicted BRDF table and fitted model, for the hemispherical maps.
    brdf_png : bytes, optional
        Those maps already drawn (:func:`printapp.report_figures.brdf_figure_png` of
        ``appearance``), as a run draws them in the background.
    preview_png, sweep_png : bytes, optional
        The preview and the light-sweep strip (``sweep_frames`` frames side by side) as
        PNG files; both are embedded as data URIs.
    highlight_png : bytes, optional
        The highlight check's spot-lit frame (:mod:`printapp.highlight_check`), shown under
        the sweep where the check applied.

    Returns
    -------
    str
        The HTML page: inline CSS, no scripts, no external references.
    """
    name = design.name
    m = manifest
    parts: list[str] = []
    add = parts.append
    add(
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>printapp report: {_e(name)}</title><style>{_STYLE}</style></head><body><main>"
    )
    add(f"<h1>printapp report: {_e(name)}</h1>")
    add(
        '<p class="explain">This page is what <code>printapp design</code> made of one design file: the '
        "printable model, how it is predicted to look once printed, and whether that meets the design's "
        "targets. It is self-contained: every picture is inside this file.</p>"
    )
    add(_verdict_section(m))
    sections = [
        ("design", "Design"),
        ("preview", "Preview"),
        ("sweep", "Light sweep"),
        ("brdf", "BRDF"),
        ("targets", "Appearance vs targets"),
        ("checks", "Checks"),
        ("mesh", "Mesh"),
        ("slicing", "Slicing"),
        ("timings", "Timings"),
        ("versions", "Versions"),
    ]
    add("<nav>" + "".join(f'<a href="#{a}">{_e(t)}</a>' for a, t in sections) + "</nav>")

    # Design.
    d = m.get("design") or {}
    add('<h2 id="design">Design</h2>')
    add(
        '<p class="explain">The design file with every default filled in (units in mm and degrees). '
        "Running it again gives the same model, byte for byte: the seeds (texture, BRDF rays, render "
        "samples, each its own) fix all randomness.</p>"
    )
    add(
        _kv_table(
            [
                ("name", name),
                ("source", d.get("source", "")),
                ("base", d.get("base", "")),
                ("texture", f"{design.texture.kind}: {texture_kind(design.texture.kind).summary}"),
                (
                    "seeds",
                    ", ".join(f"{k} {v}" for k, v in (m.get("seeds") or {}).items()),
                ),
            ]
        )
    )
    add(f"<pre>{_e(resolved_toml(design))}</pre>")
    if m.get("material"):
        add('<p class="explain">The material\'s optics, derived from its particles (Lorenz-Mie):</p>')
        add(f"<pre>{_e(json.dumps(m['material'], indent=2))}</pre>")

    # Preview.
    r = m.get("render")
    add('<h2 id="preview">Preview</h2>')
    add(
        '<p class="explain">A physically based render (Mitsuba 3 path tracing) of the model in its resin '
        "under a soft box and a small spot light. The printed relief is drawn in the cheapest way the "
        "camera cannot tell from the real thing: as geometry where its features span pixels, or as its "
        "predicted BRDF (the fitted model or the traced table) where they are smaller than a pixel.</p>"
    )
    if r:
        add(
            _kv_table(
                [
                    ("representation", r.get("representation")),
                    ("why", r.get("representation_reason")),
                    ("relief feature size", f"{r.get('relief_feature_pixels')} pixels"),
                    ("Mitsuba variant", r.get("variant")),
                    ("size", " x ".join(str(v) for v in r.get("size_px", [])) + " px"),
                    ("samples per pixel", _samples_text(r.get("spp"), r.get("noise"))),
                    *_noise_rows(r.get("noise")),
                ]
            )
        )
    add(_image(preview_png, f"preview of {name}", "Not rendered in this run.", pixels=True))

    # Light sweep.
    add('<h2 id="sweep">Light sweep</h2>')
    from printapp.rendering import sweep_azimuths_rad

    azimuths = ", ".join(f"{math.degrees(a):.0f}°" for a in sweep_azimuths_rad(0.0, sweep_frames))
    add(
        '<p class="explain">The same view with the light circling the object, one frame per position '
        f"(the light's azimuth from the camera's, left to right: {_e(azimuths)}; at 180° the light is "
        "behind the object). A brushed, anisotropic relief shows its highlight moving and stretching as "
        "the light turns; an isotropic one only brightens and dims.</p>"
    )
    add(_image(sweep_png, f"light sweep of {name}", "Not rendered in this run.", pixels=True))
    hc = m.get("highlight_check") or {}
    if highlight_png is not None and hc.get("applied"):
        add(
            '<p class="explain">The highlight check\'s frame: the same view lit by the small spot alone, '
            "at the camera's mirror image. Its long axis lies at "
            f"{hc['measured_angle_deg']:.1f}° on the screen (counter-clockwise from the right), "
            f"{hc['predicted_angle_deg']:.1f}° predicted from the BRDF lobe; it is "
            f"{hc['measured_elongation']:.2f} times longer than wide ({hc['predicted_elongation']:.2f} "
            "predicted).</p>"
        )
        add(_image(highlight_png, f"highlight check frame of {name}", "", pixels=True))

    # BRDF.
    b = m.get("brdf") or {}
    fit = b.get("fit") or {}
    add('<h2 id="brdf">BRDF: how the printed surface reflects light</h2>')
    add(
        '<p class="explain">The BRDF says how much light arriving from one direction leaves in each other '
        "direction. printapp predicts it by tracing rays through the printed microgeometry (the traced "
        "table), and builds a compact microfacet model from the same relief's facets, which renders faster "
        "and is checked against the table (where it misses by more than 10 % or three times the table's "
        "noise, the table is used, and a warning below says so). Each disc looks down on "
        "the hemisphere above the surface: the centre is straight up, the rings are 30 and 60 degrees "
        "from it, the rim is the horizon, and the angles round the rim are azimuths. Bright spots are "
        "highlights (the brightest saturate the colour scale). The third column compares the two: white "
        "where the model matches the table, red where the model reflects more, blue where it reflects "
        "less, grey where no traced ray landed. With few rays the table is speckled by noise.</p>"
    )
    if appearance is not None:
        maps = brdf_png if brdf_png is not None else brdf_figure_png(appearance)
        add(_image(maps, "BRDF maps: traced table, fitted model, difference", ""))
    else:
        add("<p><em>No BRDF was predicted in this run.</em></p>")
    if fit:
        add(_kv_table(_brdf_rows(b)))
        warnings = b.get("warnings") or []
        if warnings:
            items = "".join(f"<li>{_e(w)}</li>" for w in warnings)
            add(f'<div class="verdict fail"><strong>Warnings</strong><ul>{items}</ul></div>')

    # Appearance metrics vs targets.
    add('<h2 id="targets">Appearance against the targets</h2>')
    add(
        '<p class="explain">What a glossmeter and a profilometer would read on the printed part, predicted '
        "from its microgeometry, against the ranges the design's <code>[appearance]</code> section asks "
        "for. Gloss is in gloss units (GU: 100 is polished black glass, ISO 2813). A metric without a "
        "target is shown for information only.</p>"
    )
    head = "<tr><th>metric</th><th>predicted</th><th>target range</th><th>verdict</th><th>meaning</th></tr>"
    body = []
    for row in metric_rows(design, m):
        n = row["digits"]
        unit = f" {row['unit']}" if row["unit"] else ""
        value = "n/a" if row["value"] is None else f"{row['value']:.{n}f}{unit}"
        target = "none" if row["target"] is None else f"[{row['target'][0]:g}, {row['target'][1]:g}]{unit}"
        if row["verdict"] == "pass":
            verdict, cls = "pass", "pass"
        elif row["verdict"] == "miss":
            side = "below" if row["value"] < row["target"][0] else "above"
            verdict, cls = f"miss: {row['miss']:.{n}f}{unit} {side} the range", "miss"
        else:
            verdict, cls = row["verdict"], "none"
        body.append(
            f'<tr><td>{_e(row["metric"])}</td><td class="num">{_e(value)}</td><td>{_e(target)}</td>'
            f'<td class="{cls}">{_e(verdict)}</td><td>{_e(row["meaning"])}</td></tr>'
        )
    add(f"<table>{head}{''.join(body)}</table>")

    # Verification checks.
    v = m.get("verification") or {}
    add('<h2 id="checks">Verification checks</h2>')
    add(
        '<p class="explain">Everything checked before the model may go to the printer: that it is a valid '
        "solid that fits the printer, that the relief survives printing, that the appearance meets the "
        "targets and that the render is sane.</p>"
    )
    items = [f"<li>&#10007; <strong>{_e(x)}</strong></li>" for x in v.get("reasons", [])]
    items += [f"<li>&#10003; {_e(x)}</li>" for x in v.get("checks", [])]
    add(f'<ul class="checks">{"".join(items)}</ul>')

    # Mesh.
    bbox = m.get("bbox_mm") or {}
    relief = m.get("relief") or {}
    add('<h2 id="mesh">Mesh</h2>')
    add(
        '<p class="explain">The printable model (<code>model.stl</code>, <code>model.3mf</code>). A printer '
        "needs a closed (watertight), consistently oriented surface; the genus counts its through-holes.</p>"
    )
    mesh_rows: list[tuple[str, Any]] = [
        ("triangles", f"{m.get('triangles', 0):,}"),
        ("vertices", f"{m.get('vertices', 0):,}"),
        ("watertight", m.get("watertight")),
        ("consistently oriented", m.get("winding_consistent")),
        ("manifold (manifold3d)", m.get("manifold")),
        ("genus", m.get("genus")),
        ("volume", f"{m.get('volume_mm3', float('nan')):.2f} mm³"),
    ]
    if bbox:
        mesh_rows += [
            ("bounding box size", _fmt_mm(bbox["size"])),
            ("bounding box from", _fmt_mm(bbox["min"])),
            ("bounding box to", _fmt_mm(bbox["max"])),
        ]
    if relief:
        mesh_rows += [
            ("relief peak to valley", f"{relief.get('amplitude_mm', float('nan')) * 1000:.0f} µm"),
            ("relief RMS height (Sq)", f"{relief.get('sq_um')} µm"),
        ]
        if relief.get("softened_vertices"):
            mesh_rows.append(("vertices softened to avoid folds", f"{relief['softened_vertices']:,}"))
    add(_kv_table(mesh_rows))

    # Slicing.
    p = m.get("printer") or {}
    printed = m.get("as_printed")
    sliced = "slice" in (m.get("stages_s") or {})
    add('<h2 id="slicing">Slicing</h2>')
    add(
        '<p class="explain">The layers the resin printer cures (<code>slices.sl1</code>). The printer '
        "builds the relief out of whole layers and pixels, so what it makes differs a little from the "
        "design; for tiles that as-printed relief is reconstructed and its error measured, and the "
        "appearance is predicted from it.</p>"
    )
    slice_rows: list[tuple[str, Any]] = [
        ("printer", p.get("name")),
        ("pixel pitch", f"{p.get('pixel_pitch_mm', float('nan')) * 1000:.2f} µm"),
        ("layer height", f"{p.get('layer_height_mm', float('nan')) * 1000:.0f} µm"),
        ("layers", f"{p.get('layers')}" + ("" if sliced else " (estimated: the model was not sliced)")),
        ("anti-aliasing", p.get("antialias")),
    ]
    if m.get("max_winding") is not None:
        slice_rows.append(("largest winding number", m["max_winding"]))
    if printed:
        slice_rows += [
            ("as-printed height error, RMS", f"{printed['rms_height_error_um']} µm"),
            ("as-printed height error, max", f"{printed['max_height_error_um']} µm"),
            ("printing model", printed.get("model")),
        ]
    else:
        slice_rows.append(("as-printed height error", "measured for tiles only"))
    add(_kv_table(slice_rows))

    # Timings.
    stages = m.get("stages_s") or {}
    beside = set(m.get("stages_in_background") or [])
    wall = m.get("wall_s")
    total = wall or sum(stages.values()) or 1.0
    add('<h2 id="timings">Timings</h2>')
    add(
        '<p class="explain">Wall-clock seconds per stage of this run (they vary between runs and '
        "machines; everything else in this report does not). Stages marked <em>background</em> ran "
        "on a second thread beside the others, so the stages add up to more than the run took.</p>"
    )
    rows = "".join(
        f'<tr><td>{_e(k)}</td><td class="num">{s:.2f}</td><td>{"background" if k in beside else ""}</td>'
        f'<td><span class="bar" style="width:{300.0 * min(s / total, 1.0):.0f}px"></span></td></tr>'
        for k, s in stages.items()
    )
    add(
        f"<table><tr><th>stage</th><th>seconds</th><th>thread</th><th>share</th></tr>{rows}"
        f"<tr><th>{'the run, until this report' if wall else 'total'}</th>"
        f'<td class="num">{total:.2f}</td><td></td><td></td></tr></table>'
    )

    # Versions.
    add('<h2 id="versions">Versions</h2>')
    add('<p class="explain">The software that made these outputs, to reproduce them.</p>')
    add(_kv_table(sorted((m.get("versions") or {}).items())))
    outputs = m.get("outputs")
    if outputs:
        add(f'<p class="explain">Files written with this report: {_e(", ".join(outputs))}.</p>')
    add("</main></body></html>\n")
    return "".join(parts)

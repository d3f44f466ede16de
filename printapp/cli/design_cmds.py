"""``printapp demo`` and ``printapp design``: a design end to end."""

from pathlib import Path
from typing import Annotated, Any

import typer
from rich.text import Text

from printapp.cli.app import ForceOption, QuietOption, app, err, out, percent, warn, wrote


def _summary(name: str, manifest: dict[str, Any]) -> None:
    m = manifest
    out.print(
        f"{name}: {m['triangles']:,} triangles, watertight={m['watertight']}, "
        f"volume {m['volume_mm3']:.1f} mm^3, {m['printer']['layers']} layers on {m['printer']['name']}"
    )
    a = m["appearance"]
    out.print(
        f"predicted appearance: roughness {a['roughness']}, anisotropy {a['anisotropy']}, "
        f"highlight along {a['highlight_azimuth_deg']} deg"
    )
    b = m.get("brdf")
    if b:
        gloss = b["gloss_gu"]
        haze = f"haze {b['haze']:.1f}" if b.get("haze") is not None else f"haze {b.get('haze_reason', 'n/a')}"
        out.print(
            f"predicted gloss {gloss['20']:.1f} / {gloss['60']:.1f} / {gloss['85']:.1f} GU at 20/60/85 deg, "
            f"{haze}; compact {b['fit']['distribution']} model within "
            f"{percent(b['fit']['relative_error'])} of the traced BRDF "
            f"(table noise {percent(b['fit']['table_noise'])}; analytic "
            f"{b['fit_analytic']['distribution']} fit {percent(b['fit_analytic']['relative_error'])})"
        )
        for line in b.get("warnings", []):
            warn(line)
    rendered = m.get("render")
    if rendered:
        out.print(f"preview rendered as {rendered['representation']}: {rendered['representation_reason']}")


def _run(design_path: Path | None, out_dir: Path, force: bool, quiet: bool) -> None:
    from printapp.design_io import load_default_design, load_design

    if design_path is None:
        design, source = load_default_design(), "built-in default design"
    else:
        design, source = load_design(design_path), str(design_path)
    # After the design is read: a bad design file is refused before the pipeline's imports
    # (trimesh, SciPy, numba: 0.8 s).
    from printapp.pipeline import run_design

    outcome = run_design(design, out_dir, source=source, force=force, quiet=quiet)
    if outcome.render_warning:
        warn(outcome.render_warning)
    softened = outcome.manifest["relief"].get("softened_vertices", 0)
    if softened:
        warn(f"the relief was lowered at {softened:,} vertices where it would have folded triangles")
    _summary(design.name, outcome.manifest)
    wrote(outcome.written)
    if not outcome.passed:
        for reason in outcome.reasons:
            err.print(Text("verification failed: ", style="bold red") + Text(reason))
        if not force:
            err.print("no model written; rerun with --force to write it anyway")
        raise typer.Exit(3)


@app.command()
def demo(
    out_dir: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")] = Path("printapp-demo"),
    force: ForceOption = False,
    quiet: QuietOption = False,
) -> None:
    """Run the built-in default design end to end (no arguments needed)."""
    _run(None, out_dir, force, quiet)


@app.command()
def design(
    design_file: Annotated[Path, typer.Argument(help="Design file (TOML); see examples/.")],
    out_dir: Annotated[
        Path | None, typer.Option("--out", "-o", help="Output folder [default: NAME-out].")
    ] = None,
    force: ForceOption = False,
    quiet: QuietOption = False,
) -> None:
    """Build a design: model.stl, model.3mf, slices.sl1, preview.png, report.html, manifest.json and more."""
    _run(design_file, out_dir if out_dir is not None else Path(f"{design_file.stem}-out"), force, quiet)


@app.command()
def warmup(quiet: QuietOption = False) -> None:
    """Compile every kernel a run uses, once (make does this after installing)."""
    from printapp.warmup import warm_up

    seconds = warm_up(quiet=quiet)
    out.print(f"kernels compiled and cached in {sum(seconds.values()):.1f} s")

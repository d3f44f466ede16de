"""``printapp printers`` and ``printapp slice``: printer profiles and layers."""

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from printapp.cli.app import QuietOption, app, out, working


@app.command()
def printers() -> None:
    """List the printer profiles a design can name."""
    from slicing import PRINTERS

    table = Table("name", "printer", "display (px)", "area (mm)", "pitch (um)", "layer (mm)")
    for name, p in sorted(PRINTERS.items()):
        table.add_row(
            name,
            p.label,
            f"{p.display_pixels_x} x {p.display_pixels_y}",
            f"{p.display_width_mm:g} x {p.display_height_mm:g}",
            f"{p.pitch_mm * 1000:.2f}",
            f"{p.layer_height_mm:g} ({p.min_layer_height_mm:g}-{p.max_layer_height_mm:g})",
        )
    out.print(table)


@app.command("slice")
def slice_command(
    model: Annotated[Path, typer.Argument(help="A closed mesh (STL, OBJ, PLY, 3MF ...), in mm.")],
    out_path: Annotated[Path, typer.Option("--out", "-o", help="The .sl1 archive to write.")],
    printer: Annotated[str, typer.Option(help="Printer profile (see `printapp printers`).")] = "prusa-sl1",
    layer_height_mm: Annotated[float | None, typer.Option(help="Layer height [the profile's].")] = None,
    no_antialias: Annotated[bool, typer.Option("--no-antialias", help="Pure 0/255 pixels.")] = False,
    png_dir: Annotated[
        Path | None, typer.Option(help="Also write the layers as a PNG stack (with config.ini) here.")
    ] = None,
    quiet: QuietOption = False,
) -> None:
    """Slice a closed mesh into a PrusaSlicer-compatible .sl1 archive (and optionally a PNG stack)."""
    from printapp.slicer import slice_model_file

    with working("slicing", quiet):
        sliced = slice_model_file(
            model,
            out_path,
            printer=printer,
            layer_height_mm=layer_height_mm,
            antialias=False if no_antialias else None,
            png_dir=png_dir,
        )
    slices = sliced.slices
    out.print(
        f"{model.name}: {slices.n_layers} layers of {slices.layer_height_mm:g} mm on {sliced.printer_label}, "
        f"{sliced.volume_ml:.3f} ml of resin; wrote {out_path}" + (f" and {png_dir}/" if png_dir else "")
    )

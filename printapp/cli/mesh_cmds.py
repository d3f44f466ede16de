"""``printapp heightmap``, ``emboss``, ``displace`` and ``preview``: height maps and meshes."""

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from printapp.cli.app import QuietOption, app, out, warn, working
from printapp.errors import PrintappError

FlattenOption = Annotated[str | None, typer.Option(help="Level the base first: 'plane' or 'poly:K'.")]


@app.command()
def heightmap(
    source: Annotated[Path, typer.Argument(help="Height map: .png .tif .npy .al3d .x3p .gwy")],
    out_path: Annotated[
        Path | None, typer.Option("--out", "-o", help="Write the corrected map (.npy, mm).")
    ] = None,
    width_mm: Annotated[float | None, typer.Option(help="Images: physical width (mm).")] = None,
    depth_mm: Annotated[
        float | None, typer.Option(help="Images: physical depth, white minus black (mm).")
    ] = None,
    pitch_mm: Annotated[float | None, typer.Option(help=".npy: sample spacing (mm).")] = None,
    remove_outliers: Annotated[
        bool, typer.Option(help="Mask samples beyond 5 robust sigmas, then fill.")
    ] = False,
    flatten: FlattenOption = None,
    crop: Annotated[str | None, typer.Option(help="Keep columns C0:C1 and rows R0:R1 (samples).")] = None,
    json_out: Annotated[Path | None, typer.Option("--json", help="Write the parameters as JSON.")] = None,
    quiet: QuietOption = False,
) -> None:
    """Correct a measured or image height map and print its ISO 25178 roughness parameters."""
    from printapp.topography import analyse_heightmap

    with working("reading and correcting the height map", quiet):
        summary = analyse_heightmap(
            source,
            out=out_path,
            json_out=json_out,
            width_mm=width_mm,
            depth_mm=depth_mm,
            pitch_mm=pitch_mm,
            remove_outliers=remove_outliers,
            flatten=flatten,
            crop=crop,
        )
    ny, nx = summary["samples"]
    px_um, py_um = summary["pitch_um"]
    title = (
        f"{source.name}: {nx} x {ny} samples, "
        f"pitch {px_um:.4g} x {py_um:.4g} um, {summary['filled_samples']} filled"
    )
    table = Table("parameter", "value", title=title)
    for name, value in summary["parameters"].items():
        table.add_row(name, f"{value:.6g}")
    out.print(table)


@app.command()
def emboss(
    source: Annotated[Path, typer.Argument(help="Height map (as for `printapp heightmap`).")],
    out_path: Annotated[Path, typer.Option("--out", "-o", help="The closed slab to write (.stl).")],
    width_mm: Annotated[float | None, typer.Option(help="Physical width (mm); images need it.")] = None,
    depth_mm: Annotated[
        float | None, typer.Option(help="Relief depth, white minus black (mm); images need it.")
    ] = None,
    base_mm: Annotated[float, typer.Option(help="Solid thickness under the relief (mm).")] = 2.0,
    pitch_mm: Annotated[
        float | None, typer.Option(help="Resample to this pitch [the printer's pixel].")
    ] = None,
    printer: Annotated[str, typer.Option(help="Printer whose pixel pitch is the default.")] = "prusa-sl1",
    flatten: FlattenOption = None,
    max_error_um: Annotated[
        float | None,
        typer.Option(help="Adaptive top: fewest triangles keeping every sample within this (um)."),
    ] = None,
    quiet: QuietOption = False,
) -> None:
    """Turn a height map into a closed, printable slab (the talk's Blender step, as one command).

    The map is low-pass filtered and resampled to the printer's pixel pitch (no more
    triangles than the printer can print), lifted to start at zero, and closed with walls
    and a floor.
    """
    from printapp.emboss import emboss_heightmap

    with working("embossing the slab", quiet):
        slab = emboss_heightmap(
            source,
            out_path,
            width_mm=width_mm,
            depth_mm=depth_mm,
            base_mm=base_mm,
            pitch_mm=pitch_mm,
            printer=printer,
            flatten=flatten,
            max_error_um=max_error_um,
        )
    if slab.worst_error_mm is not None:
        worst_um = slab.worst_error_mm * 1000
        out.print(f"adaptive top: every sample within {worst_um:.3g} um (bound {max_error_um:g} um)")
    field = slab.field
    ny, nx = field.shape
    out.print(
        f"{source.name}: {nx} x {ny} samples at {field.pitch_x_mm * 1000:.1f} um, "
        f"{slab.triangles:,} triangles, closed slab {field.width_mm:.2f} x {field.depth_mm:.2f} x "
        f"{slab.base_mm + float(field.heights_mm.max()):.3f} mm; wrote {out_path}"
    )


@app.command()
def displace(
    model: Annotated[Path, typer.Argument(help="A closed mesh (with --repair, any mesh).")],
    out_path: Annotated[Path, typer.Option("--out", "-o", help="Output: .stl, .3mf, .ply or .obj (+ .mtl).")],
    amplitude_mm: Annotated[float, typer.Option(help="Peak-to-valley height of the relief (mm).")],
    texture: Annotated[str, typer.Option(help="scn, fbm, turbulence or lic.")] = "fbm",
    feature_size_mm: Annotated[float, typer.Option(help="Size of one noise cell (mm).")] = 2.0,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    octaves: Annotated[int, typer.Option(help="fbm: octaves.")] = 4,
    field: Annotated[
        str, typer.Option(help="Direction field (see README): lic's streamlines, the stretch of the others.")
    ] = "swirl",
    stretch: Annotated[
        float, typer.Option(help="scn, fbm, turbulence: features this many times longer along --field.")
    ] = 1.0,
    length_mm: Annotated[float, typer.Option(help="lic: streamline half-length (mm).")] = 2.0,
    scale: Annotated[float, typer.Option(help="mm per unit of the mesh file (25.4 for inches).")] = 1.0,
    printer: Annotated[str, typer.Option(help="Printer whose pixel pitch bounds the detail.")] = "prusa-sl1",
    repair: Annotated[bool, typer.Option("--repair", help="Close open meshes with pymeshfix first.")] = False,
    refractive_index: Annotated[float, typer.Option(help=".obj: the resin's index for the .mtl.")] = 1.5,
    quiet: QuietOption = False,
) -> None:
    """Displace a closed mesh along its angle-weighted normals by a texture; keep it a valid solid."""
    from printapp.displace import displace_mesh_file

    with working("displacing the mesh", quiet):
        result = displace_mesh_file(
            model,
            out_path,
            amplitude_mm=amplitude_mm,
            texture=texture,
            feature_size_mm=feature_size_mm,
            seed=seed,
            octaves=octaves,
            field=field,
            stretch=stretch,
            length_mm=length_mm,
            scale=scale,
            printer=printer,
            repair=repair,
            refractive_index=refractive_index,
        )
    if result.repair_note:
        out.print(result.repair_note)
    if result.overlap_note:
        warn(result.overlap_note)
    if result.softened_vertices:
        warn(
            f"the relief was lowered at {result.softened_vertices:,} vertices "
            "where it would have folded thin or tightly curved triangles"
        )
    if result.frame is not None:
        frame = result.frame
        out.print(
            f"stretched {stretch:g}x along {frame.field} in each vertex's tangent frame; "
            f"{frame.singular_vertices:,} singular vertices (the field vanishes or turns there: isotropic), "
            f"blended over {frame.blend_radius_mm:g} mm"
        )
    solid = result.solid
    out.print(
        f"{model.name}: {solid.triangles:,} triangles, genus {solid.genus}, "
        f"volume {solid.volume_mm3:.1f} mm^3, watertight={solid.watertight}; wrote {out_path}"
    )


@app.command()
def preview(
    model: Annotated[Path, typer.Argument(help="Any mesh (.stl .ply .obj .3mf .off).")],
    out_path: Annotated[Path, typer.Option("--out", "-o", help="The image to write (.png).")] = Path(
        "view.png"
    ),
    width_px: Annotated[int, typer.Option(min=16, max=4096)] = 800,
    height_px: Annotated[int, typer.Option(min=16, max=4096)] = 600,
    quiet: QuietOption = False,
) -> None:
    """A quick off-screen look at any mesh (pyvista, no path tracing)."""
    from printapp.viewer import quick_view

    if out_path.suffix.lower() != ".png":
        raise PrintappError(f"{out_path}: expected an image file ending in .png")
    with working("drawing the mesh (pyvista)", quiet):
        faces = quick_view(model, out_path, width_px, height_px)
    out.print(f"{model.name}: {faces:,} triangles; wrote {out_path}")

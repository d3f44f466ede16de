"""The ``printapp`` command line: a thin shell over functions that tests call directly.

Heavy libraries (numba kernels, trimesh, Mitsuba, matplotlib) are imported inside
the commands that need them, so ``printapp --help`` starts fast.
"""

from __future__ import annotations

import sys
import zipfile
from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from printapp.errors import PrintappError

app = typer.Typer(
    name="printapp",
    help="Appearance printing: textures to watertight resin prints, verified by path tracing.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
_err = Console(stderr=True, highlight=False, soft_wrap=True)
_out = Console(highlight=False, soft_wrap=True)
if not _out.is_terminal:
    _out.width = 160  # piped output: do not squeeze tables to 80 columns

QuietOption = Annotated[
    bool, typer.Option("--quiet", "-q", help="No progress bars, only the summary and errors.")
]
ForceOption = Annotated[
    bool, typer.Option("--force", help="Write the model even when the design fails verification.")
]


def _percent(value: float | None) -> str:
    return "n/a (too few rays)" if value is None else f"{value:.1%}"


def _fail(exc: PrintappError) -> typer.Exit:
    _err.print(f"[bold red]error:[/] {exc}", markup=True, highlight=False)
    return typer.Exit(exc.exit_code)


def _version_callback(value: bool) -> None:
    if value:
        from importlib.metadata import version

        _out.print(f"printapp {version('printapp')}")
        raise typer.Exit(0)


@app.callback()
def _root(
    version: Annotated[
        bool, typer.Option("--version", callback=_version_callback, is_eager=True, help="Show the version.")
    ] = False,
) -> None:
    """Appearance printing: textures to watertight resin prints, verified by path tracing."""


def _run(design_path: Path | None, out_dir: Path, force: bool, quiet: bool) -> None:
    from printapp.design import load_design
    from printapp.pipeline import load_default_design, run_design

    try:
        if design_path is None:
            design, source = load_default_design(), "built-in default design"
        else:
            design, source = load_design(design_path), str(design_path)
        outcome = run_design(design, out_dir, source=source, force=force, quiet=quiet)
    except PrintappError as exc:
        raise _fail(exc) from None
    if outcome.render_warning:
        _err.print(f"warning: {outcome.render_warning}")
    softened = outcome.manifest["relief"].get("softened_vertices", 0)
    if softened:
        _err.print(
            f"warning: the relief was lowered at {softened:,} vertices where it would have folded triangles"
        )
    m = outcome.manifest
    _out.print(
        f"{design.name}: {m['triangles']:,} triangles, watertight={m['watertight']}, "
        f"volume {m['volume_mm3']:.1f} mm^3, {m['printer']['layers']} layers on {m['printer']['name']}"
    )
    a = m["appearance"]
    _out.print(
        f"predicted appearance: roughness {a['roughness']}, anisotropy {a['anisotropy']}, "
        f"highlight along {a['highlight_azimuth_deg']} deg"
    )
    b = m.get("brdf")
    if b:
        gloss = b["gloss_gu"]
        _out.print(
            f"predicted gloss {gloss['20']:.1f} / {gloss['60']:.1f} / {gloss['85']:.1f} GU at 20/60/85 deg, "
            f"haze {b['haze']:.1f}; fitted {b['fit']['distribution']} model within "
            f"{_percent(b['fit']['relative_error'])} of the traced BRDF "
            f"(table noise {_percent(b['fit']['table_noise'])})"
        )
    rendered = m.get("render")
    if rendered:
        _out.print(f"preview rendered as {rendered['representation']}: {rendered['representation_reason']}")
    for path in outcome.written:
        _out.print(f"  wrote {path}")
    if not outcome.passed:
        for reason in outcome.reasons:
            _err.print(f"[bold red]verification failed:[/] {reason}", markup=True)
        if not force:
            _err.print("no model written; rerun with --force to write it anyway")
        raise typer.Exit(3)


@app.command()
def demo(
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")] = Path("printapp-demo"),
    force: ForceOption = False,
    quiet: QuietOption = False,
) -> None:
    """Run the built-in default design end to end (no arguments needed)."""
    _run(None, out, force, quiet)


@app.command()
def design(
    design_file: Annotated[Path, typer.Argument(help="Design file (TOML); see examples/.")],
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Output folder [default: NAME-out].")
    ] = None,
    force: ForceOption = False,
    quiet: QuietOption = False,
) -> None:
    """Build a design: model.stl, model.3mf, slices.sl1, preview.png, report.html, manifest.json and more."""
    _run(design_file, out if out is not None else Path(f"{design_file.stem}-out"), force, quiet)


class TextureKind(StrEnum):
    scn = "scn"
    fbm = "fbm"
    turbulence = "turbulence"
    marble = "marble"
    lic = "lic"


@app.command()
def texture(
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Output: .png (8-bit grey) or .npy (raw float64).")
    ],
    kind: Annotated[
        TextureKind | None, typer.Argument(help="scn, fbm, turbulence, marble or lic (or --from).")
    ] = None,
    from_file: Annotated[
        Path | None,
        typer.Option("--from", help="A design or `printapp fit` fragment: its texture table in colour."),
    ] = None,
    width_mm: Annotated[
        float | None, typer.Option(help="--from: side of the square shown (mm; default: the tile's width).")
    ] = None,
    size: Annotated[int, typer.Option(min=2, max=8192, help="Image side (pixels).")] = 512,
    cells: Annotated[
        float | None, typer.Option(min=1e-6, help="Noise cells across the image [8; lic: size/2].")
    ] = None,
    seed: Annotated[int, typer.Option(min=0, help="Random seed.")] = 0,
    impulses: Annotated[int, typer.Option(min=1, max=1024, help="Impulses per cell N.")] = 30,
    cell_seed: Annotated[str, typer.Option(help="'hash' or the talk's 'frisvad'.")] = "hash",
    octaves: Annotated[int, typer.Option(min=1, max=24, help="fbm: octaves.")] = 5,
    lacunarity: Annotated[float, typer.Option(help="fbm: frequency ratio between octaves (> 1).")] = 2.0,
    hurst: Annotated[float, typer.Option("--H", help="fbm: fractional increment in (0, 1].")] = 1.0,
    low: Annotated[int, typer.Option(min=0, help="turbulence: first octave.")] = 0,
    high: Annotated[int, typer.Option(min=0, help="turbulence: last octave.")] = 4,
    contrast: Annotated[
        float, typer.Option("--A", help="marble: contrast A in 0.5 (A noise(B p) + 1).")
    ] = 1.0,
    frequency: Annotated[float, typer.Option("--B", help="marble: frequency B.")] = 1.0,
    field: Annotated[
        str, typer.Option(help="lic: 'constant:ANGLE' (degrees), 'swirl' or 'image:FILE' (angle map).")
    ] = "swirl",
    length: Annotated[float, typer.Option(help="lic: streamline half-length (pixels).")] = 15.0,
) -> None:
    """Write a texture image: sparse convolution noise, fBm, turbulence, marble, or LIC along a field.

    PNG images of scn, fbm, turbulence and lic are scaled from their minimum to their
    maximum; marble is 0.5 (A noise(B p) + 1) clipped to [0, 1]. .npy files hold the raw
    values. lic convolves sparse convolution noise (2-pixel features unless --cells says
    otherwise) along the streamlines of --field. With --from FILE, the texture of a design
    (or of a fragment written by `printapp fit`) on a square of --width-mm, coloured by its
    palette; .npy then holds its values.
    """
    import numpy as np

    import noise
    from printapp.exporters import atomic_write_bytes

    suffix = out.suffix.lower()
    if suffix not in (".png", ".npy"):
        raise _fail(PrintappError(f"{out}: expected an output file ending in .png or .npy"))
    if from_file is not None or kind is None:
        from printapp.texture import write_texture_from_file

        try:
            if kind is not None:
                raise PrintappError(f"give either KIND ({kind.value}) or --from FILE, not both")
            if from_file is None:
                raise PrintappError("expected a texture KIND (scn, fbm, turbulence, marble, lic) or --from")
            _out.print(write_texture_from_file(from_file, out, size, width_mm))
        except PrintappError as exc:
            raise _fail(exc) from None
        return
    if cells is None:
        cells = size / 2.0 if kind is TextureKind.lic else 8.0
    axis = (np.arange(size) + 0.5) * (cells / size)
    common = {"seed": seed, "impulses": impulses, "cell_seed": cell_seed}
    try:
        if kind is TextureKind.scn:
            values = noise.sparse_convolution_grid(axis, axis, **common)
        elif kind is TextureKind.fbm:
            values = noise.fbm_grid(axis, axis, octaves=octaves, lacunarity=lacunarity, H=hurst, **common)
        elif kind is TextureKind.turbulence:
            values = noise.turbulence_grid(axis, axis, low=low, high=high, **common)
        elif kind is TextureKind.lic:
            from noise.lic import lic2d
            from printapp.fields import field_on_grid

            pixels = np.arange(size, dtype=float)
            u, v = field_on_grid(field, pixels, pixels)
            values = lic2d(u, v, noise.sparse_convolution_grid(axis, axis, **common), length=length)
        else:
            if not (np.isfinite(contrast) and np.isfinite(frequency)):
                raise ValueError("A, B: expected finite numbers")
            values = 0.5 * (
                contrast * noise.sparse_convolution_grid(axis * frequency, axis * frequency, **common) + 1
            )
    except ValueError as exc:
        name, _, rest = str(exc).partition(":")
        if name.startswith("expected"):  # from the field spec parser
            raise _fail(PrintappError(f"--field: {exc}")) from None
        raise _fail(PrintappError(f"--{name.replace('_', '-')}:{rest}")) from None
    except PrintappError as exc:
        raise _fail(exc) from None
    try:
        if suffix == ".npy":
            import io

            buffer = io.BytesIO()
            np.save(buffer, values)
            atomic_write_bytes(out, buffer.getvalue())
        else:
            import io

            from PIL import Image

            if kind is TextureKind.marble:
                unit = np.clip(values, 0.0, 1.0)
            else:
                span = float(values.max() - values.min())
                unit = (values - values.min()) / span if span > 0 else np.zeros_like(values)
            buffer = io.BytesIO()
            Image.fromarray(np.round(unit[::-1] * 255).astype(np.uint8), mode="L").save(buffer, format="PNG")
            atomic_write_bytes(out, buffer.getvalue())
    except PrintappError as exc:
        raise _fail(exc) from None
    _out.print(f"{kind.value}: {size}x{size}, mean {values.mean():.4f}, std {values.std():.4f}; wrote {out}")


@app.command()
def printers() -> None:
    """List the printer profiles a design can name."""
    from rich.table import Table

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
    _out.print(table)


def _flatten_order(flatten: str | None) -> int | None:
    if flatten is None:
        return None
    if flatten == "plane":
        return 1
    kind, _, degree = flatten.partition(":")
    if kind == "poly" and degree.isdigit() and 0 <= int(degree) <= 8:
        return int(degree)
    raise PrintappError(f"--flatten: expected 'plane' or 'poly:K' with K in 0..8, got '{flatten}'")


def _crop_window(crop: str | None, shape: tuple[int, int]) -> tuple[slice, slice]:
    if crop is None:
        return slice(None), slice(None)
    try:
        cols, rows = crop.split(",")
        c0, c1 = (int(v) for v in cols.split(":"))
        r0, r1 = (int(v) for v in rows.split(":"))
    except ValueError:
        raise PrintappError(f"--crop: expected 'C0:C1,R0:R1' in samples, got '{crop}'") from None
    if not (0 <= c0 < c1 <= shape[1] and 0 <= r0 < r1 <= shape[0] and c1 - c0 >= 2 and r1 - r0 >= 2):
        raise PrintappError(
            f"--crop: '{crop}' is not a window of at least 2 x 2 samples inside {shape[1]} x {shape[0]}"
        )
    return slice(r0, r1), slice(c0, c1)


def _load_corrected(
    path: Path,
    width_mm: float | None,
    depth_mm: float | None,
    pitch_mm: float | None,
    remove_outliers: bool,
    flatten: str | None,
    crop: str | None = None,
):
    """Read a height map, crop it, and apply the corrections; missing data is always filled."""
    import numpy as np

    from printapp.topography import fill_masked, level, mask_outliers, read_heightmap

    order = _flatten_order(flatten)
    topo = read_heightmap(path, width_mm=width_mm, depth_mm=depth_mm, pitch_mm=pitch_mm)
    heights = topo.heights_mm[_crop_window(crop, topo.heights_mm.shape)]
    mask = mask_outliers(heights) if remove_outliers else ~np.isfinite(heights)
    heights = fill_masked(heights, mask)
    if order is not None:
        heights = level(heights, order)
    return heights, topo.pitch_x_mm, topo.pitch_y_mm, int(mask.sum())


@app.command()
def heightmap(
    source: Annotated[Path, typer.Argument(help="Height map: .png .tif .npy .al3d .x3p .gwy")],
    out: Annotated[
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
    flatten: Annotated[str | None, typer.Option(help="Level the base: 'plane' or 'poly:K'.")] = None,
    crop: Annotated[str | None, typer.Option(help="Keep columns C0:C1 and rows R0:R1 (samples).")] = None,
    json_out: Annotated[Path | None, typer.Option("--json", help="Write the parameters as JSON.")] = None,
) -> None:
    """Correct a measured or image height map and print its ISO 25178 roughness parameters."""
    import io
    import json

    import numpy as np
    from rich.table import Table

    from printapp.exporters import atomic_write_files
    from printapp.topography import roughness

    try:
        if out is not None and out.suffix.lower() != ".npy":
            raise PrintappError(f"{out}: expected an output file ending in .npy")
        heights, px, py, filled = _load_corrected(
            source, width_mm, depth_mm, pitch_mm, remove_outliers, flatten, crop
        )
        r = roughness(heights, px, py)
        values = {
            "Sa_um": r.sa_um,
            "Sq_um": r.sq_um,
            "Sz_um": r.sz_um,
            "Ssk": r.ssk,
            "Sku": r.sku,
            "Sdq": r.sdq,
            "Sdr_percent": r.sdr_percent,
        }
        summary = {
            "file": str(source),
            "samples": list(heights.shape),
            "pitch_um": [px * 1000, py * 1000],
            "filled_samples": filled,
            "flatten": flatten,
            "parameters": values,
        }
        outputs = []
        if json_out is not None:
            outputs.append((json_out, (json.dumps(summary, indent=2) + "\n").encode()))
        if out is not None:
            buffer = io.BytesIO()
            np.save(buffer, heights)
            outputs.append((out, buffer.getvalue()))
        atomic_write_files(outputs)
    except PrintappError as exc:
        raise _fail(exc) from None
    title = (
        f"{source.name}: {heights.shape[1]} x {heights.shape[0]} samples, "
        f"pitch {px * 1000:.4g} x {py * 1000:.4g} um, {filled} filled"
    )
    table = Table("parameter", "value", title=title)
    for name, value in values.items():
        table.add_row(name, f"{value:.6g}")
    _out.print(table)


@app.command()
def emboss(
    source: Annotated[Path, typer.Argument(help="Height map (as for `printapp heightmap`).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="The closed slab to write (.stl).")],
    width_mm: Annotated[float | None, typer.Option(help="Physical width (mm); images need it.")] = None,
    depth_mm: Annotated[
        float | None, typer.Option(help="Relief depth, white minus black (mm); images need it.")
    ] = None,
    base_mm: Annotated[float, typer.Option(help="Solid thickness under the relief (mm).")] = 2.0,
    pitch_mm: Annotated[
        float | None, typer.Option(help="Resample to this pitch [the printer's pixel].")
    ] = None,
    printer: Annotated[str, typer.Option(help="Printer whose pixel pitch is the default.")] = "prusa-sl1",
    flatten: Annotated[str | None, typer.Option(help="Level the base first: 'plane' or 'poly:K'.")] = None,
    max_error_um: Annotated[
        float | None,
        typer.Option(help="Adaptive top: fewest triangles keeping every sample within this (um)."),
    ] = None,
) -> None:
    """Turn a height map into a closed, printable slab (the talk's Blender step, as one command).

    The map is low-pass filtered and resampled to the printer's pixel pitch (no more
    triangles than the printer can print), lifted to start at zero, and closed with walls
    and a floor.
    """
    import numpy as np

    from noise.heightfield import HeightField
    from printapp.exporters import atomic_write_bytes, ply_bytes, stl_bytes, threemf_bytes
    from printapp.slab import adaptive_slab_arrays, slab_arrays
    from slicing import PRINTERS

    try:
        if printer not in PRINTERS:
            raise PrintappError(
                f"--printer: unknown printer '{printer}', expected one of {', '.join(PRINTERS)}"
            )
        if out.suffix.lower() not in (".stl", ".3mf", ".ply", ".obj"):
            raise PrintappError(f"{out}: expected an output file ending in .stl, .3mf, .ply or .obj")
        if not (base_mm > 0):
            raise PrintappError(f"--base-mm: expected a positive thickness, got {base_mm}")
        target = PRINTERS[printer].pitch_mm if pitch_mm is None else pitch_mm
        if not (target > 0):
            raise PrintappError(f"--pitch-mm: expected a positive pitch, got {pitch_mm}")
        heights, px, py, _ = _load_corrected(source, width_mm, depth_mm, None, False, flatten)
        if source.suffix.lower() in (".npy",):
            raise PrintappError(
                f"{source}: give an image or a measured map to emboss (a .npy has no depth scale)"
            )
        width, depth = (heights.shape[1] - 1) * px, (heights.shape[0] - 1) * py
        nx, ny = max(2, round(width / target) + 1), max(2, round(depth / target) + 1)
        if nx * ny > 16_000_000:
            raise PrintappError(
                f"--pitch-mm: {target:g} mm gives {nx} x {ny} samples; expected at most 16 million"
            )
        if max_error_um is not None:
            if not (max_error_um >= 0):
                raise PrintappError(f"--max-error-um: expected a number >= 0, got {max_error_um}")
            # The adaptive top needs a square grid of 2^k + 1 samples: the next size up.
            side = 1
            while side < max(nx, ny) - 1:
                side *= 2
            nx = ny = side + 1
        if (ny, nx) == heights.shape:
            resampled = heights.copy()  # already at the pitch asked for
        else:
            from scipy.ndimage import gaussian_filter, map_coordinates

            # Anti-alias before decimating: a Gaussian whose sigma is half the new pitch in samples.
            sigma = (max(0.0, 0.5 * (target / px - 1)), max(0.0, 0.5 * (target / py - 1)))
            smooth = gaussian_filter(heights, sigma=(sigma[1], sigma[0]), mode="nearest")
            rows = np.linspace(0, heights.shape[0] - 1, ny)
            cols = np.linspace(0, heights.shape[1] - 1, nx)
            rr, cc = np.meshgrid(rows, cols, indexing="ij")
            resampled = map_coordinates(smooth, [rr, cc], order=1, mode="nearest")
        resampled -= resampled.min()
        field = HeightField(resampled, width / (nx - 1), depth / (ny - 1))
        # Closed and consistently oriented by construction (see slab_from_heightfield and
        # its invariant tests), so the costly checks `printapp design` runs are skipped here.
        if max_error_um is None:
            vertices, faces = slab_arrays(field, base_mm)
        else:
            vertices, faces, worst_mm = adaptive_slab_arrays(
                resampled, width, depth, base_mm, max_error_um / 1000
            )
        suffix = out.suffix.lower()
        if suffix == ".stl":
            atomic_write_bytes(out, stl_bytes(vertices, faces))
        elif suffix == ".ply":
            atomic_write_bytes(out, ply_bytes(vertices, faces))
        elif suffix == ".3mf":
            atomic_write_bytes(out, threemf_bytes(vertices, faces, out.stem))
        else:
            _write_model(out, _ArraysMesh(vertices, faces))
    except PrintappError as exc:
        raise _fail(exc) from None
    if max_error_um is not None:
        _out.print(f"adaptive top: every sample within {worst_mm * 1000:.3g} um (bound {max_error_um:g} um)")
    _out.print(
        f"{source.name}: {nx} x {ny} samples at {field.pitch_x_mm * 1000:.1f} um, "
        f"{len(faces):,} triangles, closed slab {field.width_mm:.2f} x {field.depth_mm:.2f} x "
        f"{base_mm + float(resampled.max()):.3f} mm; wrote {out}"
    )


class _ArraysMesh:
    """Vertices and faces with the two attributes the writers read."""

    def __init__(self, vertices, faces) -> None:
        self.vertices = vertices
        self.faces = faces


def _write_model(out: Path, mesh, refractive_index: float = 1.5) -> None:
    """Write a mesh by the output's suffix: .stl, .3mf, .ply, or .obj (with its .mtl)."""
    from printapp.exporters import (
        OutputFolder,
        atomic_write_bytes,
        obj_files,
        ply_bytes,
        stl_bytes,
        threemf_bytes,
    )

    suffix = out.suffix.lower()
    if suffix == ".stl":
        atomic_write_bytes(out, stl_bytes(mesh.vertices, mesh.faces))
    elif suffix == ".3mf":
        atomic_write_bytes(out, threemf_bytes(mesh.vertices, mesh.faces, out.stem))
    elif suffix == ".ply":
        atomic_write_bytes(out, ply_bytes(mesh.vertices, mesh.faces))
    elif suffix == ".obj":
        obj, mtl = obj_files(mesh.vertices, mesh.faces, out.stem, refractive_index)
        with OutputFolder(out.parent if str(out.parent) else Path(".")) as folder:
            folder.write_text(out.name, obj)
            folder.write_text(f"{out.stem}.mtl", mtl)
            folder.commit()
    else:
        raise PrintappError(f"{out}: expected an output file ending in .stl, .3mf, .ply or .obj")


@app.command()
def displace(
    model: Annotated[Path, typer.Argument(help="A closed mesh (with --repair, any mesh).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output: .stl, .3mf, .ply or .obj (+ .mtl).")],
    amplitude_mm: Annotated[float, typer.Option(help="Peak-to-valley height of the relief (mm).")],
    texture: Annotated[str, typer.Option(help="scn, fbm, turbulence or lic.")] = "fbm",
    feature_size_mm: Annotated[float, typer.Option(help="Size of one noise cell (mm).")] = 2.0,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    octaves: Annotated[int, typer.Option(help="fbm: octaves.")] = 4,
    field: Annotated[str, typer.Option(help="lic: direction field (see README).")] = "swirl",
    length_mm: Annotated[float, typer.Option(help="lic: streamline half-length (mm).")] = 2.0,
    scale: Annotated[float, typer.Option(help="mm per unit of the mesh file (25.4 for inches).")] = 1.0,
    printer: Annotated[str, typer.Option(help="Printer whose pixel pitch bounds the detail.")] = "prusa-sl1",
    repair: Annotated[bool, typer.Option("--repair", help="Close open meshes with pymeshfix first.")] = False,
    refractive_index: Annotated[float, typer.Option(help=".obj: the resin's index for the .mtl.")] = 1.5,
) -> None:
    """Displace a closed mesh along its angle-weighted normals by a texture; keep it a valid solid."""
    from printapp.design import design_from_dict
    from printapp.mesh import check_solid, folded_triangles, load_closed_mesh
    from printapp.pipeline import build_relief
    from slicing import PRINTERS, slice_mesh

    try:
        if out.suffix.lower() not in (".stl", ".3mf", ".ply", ".obj"):
            raise PrintappError(f"{out}: expected an output file ending in .stl, .3mf, .ply or .obj")
        options = {
            "base": {"shape": "mesh", "path": str(model), "scale": scale},
            "texture": {
                "kind": texture,
                "feature_size_mm": feature_size_mm,
                "seed": seed,
                "octaves": octaves,
                "field": field,
                "length_mm": length_mm,
            },
            "relief": {"amplitude_mm": amplitude_mm},
            "printer": {"name": printer},
        }
        design = design_from_dict(options, "options")
        base = load_closed_mesh(model, scale, repair=repair)
        relief = build_relief(design, base=base)
        if folded_triangles(relief.undisplaced, relief.mesh):
            raise PrintappError(f"{model}: the displaced mesh still folds over; use a smaller --amplitude-mm")
        solid = check_solid(relief.mesh)
        if not solid.ok:
            raise PrintappError(f"{model}: the displaced mesh is not a valid solid ({solid.manifold_status})")
        try:
            # What the printer would see: a surface passing through itself winds twice.
            winding = slice_mesh(relief.mesh.vertices, relief.mesh.faces, PRINTERS[printer]).max_winding()
        except ValueError:
            winding = None  # larger than this printer: no layers to look at
        if winding is not None and 1.01 < winding < 1.5:
            _err.print(
                f"warning: the surface overlaps itself by less than half a pixel somewhere "
                f"(winding number {winding:.2f}); the printer cures the union"
            )
        if winding is not None and winding >= 1.5:
            raise PrintappError(
                f"--amplitude-mm: {amplitude_mm:g} mm makes the surface pass through itself "
                f"(winding number {winding:.2f}); use a smaller amplitude or larger features"
            )
        _write_model(out, relief.mesh, refractive_index)
    except PrintappError as exc:
        raise _fail(exc) from None
    if relief.softened_vertices:
        _err.print(
            f"warning: the relief was lowered at {relief.softened_vertices:,} vertices "
            "where it would have folded thin or tightly curved triangles"
        )
    _out.print(
        f"{model.name}: {solid.triangles:,} triangles, genus {solid.genus}, "
        f"volume {solid.volume_mm3:.1f} mm^3, watertight={solid.watertight}; wrote {out}"
    )


@app.command("slice")
def slice_command(
    model: Annotated[Path, typer.Argument(help="A closed mesh (STL, OBJ, PLY, 3MF ...), in mm.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="The .sl1 archive to write.")],
    printer: Annotated[str, typer.Option(help="Printer profile (see `printapp printers`).")] = "prusa-sl1",
    layer_height_mm: Annotated[float | None, typer.Option(help="Layer height [the profile's].")] = None,
    no_antialias: Annotated[bool, typer.Option("--no-antialias", help="Pure 0/255 pixels.")] = False,
    png_dir: Annotated[
        Path | None, typer.Option(help="Also write the layers as a PNG stack (with config.ini) here.")
    ] = None,
) -> None:
    """Slice a closed mesh into a PrusaSlicer-compatible .sl1 archive (and optionally a PNG stack)."""
    import difflib
    import io

    from printapp.exporters import OutputFolder, atomic_write_bytes
    from printapp.mesh import load_closed_mesh
    from slicing import PRINTERS, slice_mesh, write_sl1
    from slicing.sl1 import encoded_layers

    try:
        if printer not in PRINTERS:
            close = difflib.get_close_matches(printer, PRINTERS, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise PrintappError(
                f"--printer: unknown printer '{printer}', expected one of {', '.join(PRINTERS)}{hint}"
            )
        if out.suffix.lower() != ".sl1":
            raise PrintappError(f"{out}: expected an output file ending in .sl1")
        mesh = load_closed_mesh(model)
        try:
            slices = slice_mesh(
                mesh.vertices,
                mesh.faces,
                PRINTERS[printer],
                layer_height_mm=layer_height_mm,
                antialias=False if no_antialias else None,
            )
        except ValueError as exc:
            raise PrintappError(f"{model}: {exc}") from None
        buffer = io.BytesIO()
        stats = write_sl1(buffer, slices, out.stem)
        if png_dir is None:
            atomic_write_bytes(out, buffer.getvalue())
        else:
            # The PNG stack is staged first and moved in only once the .sl1 is written.
            with OutputFolder(png_dir) as folder:
                with zipfile.ZipFile(io.BytesIO(buffer.getvalue())) as archive:
                    folder.write_bytes("config.ini", archive.read("config.ini"))
                for k, png in encoded_layers(slices):
                    folder.write_bytes(f"{k:05d}.png", png)
                atomic_write_bytes(out, buffer.getvalue())
                folder.commit()
    except PrintappError as exc:
        raise _fail(exc) from None
    label = PRINTERS[printer].label
    _out.print(
        f"{model.name}: {slices.n_layers} layers of {slices.layer_height_mm:g} mm on {label}, "
        f"{stats.volume_ml:.3f} ml of resin; wrote {out}" + (f" and {png_dir}/" if png_dir else "")
    )


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
    out: Annotated[Path, typer.Option("--out", "-o", help="The table to write (.npz).")] = Path("brdf.npz"),
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
    seed: Annotated[int, typer.Option(min=0, help="Seed of the rays.")] = 0,
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
) -> None:
    """Predict the BRDF of a printed surface by tracing rays through its microgeometry.

    Writes the bin-averaged table (brdf.npz), and optionally a plot and the appearance
    metrics: albedo, gloss at 20/60/85 deg (ISO 2813), haze, the highlight's
    anisotropy, and the fitted compact microfacet model with its error.
    """
    import json

    from noise.heightfield import HeightField
    from printapp.brdf import (
        MESH_SUFFIXES,
        brdf_arrays,
        brdf_plot_png,
        grey_albedo,
        heightfield_from_mesh,
        npz_bytes,
        parse_incident,
    )
    from printapp.exporters import atomic_write_files
    from render.appearance import DEFAULT_INCIDENT_DEG, predict_appearance

    try:
        if out.suffix.lower() != ".npz":
            raise PrintappError(f"{out}: expected an output file ending in .npz")
        if plot is not None and plot.suffix.lower() != ".png":
            raise PrintappError(f"{plot}: expected a plot file ending in .png")
        incident = parse_incident(incident_deg) or DEFAULT_INCIDENT_DEG
        suffix = source.suffix.lower()
        design_ior, design_albedo, design_lobe_error, origin = 1.5, 0.8, None, "height map"
        if suffix == ".toml":
            from printapp.design import load_design
            from printapp.pipeline import appearance_field

            design = load_design(source)
            field, origin = appearance_field(design)
            design_ior = design.material.refractive_index
            design_albedo = grey_albedo(design.material.body_albedo)
            design_lobe_error = design.brdf.lobe_error
        elif suffix in MESH_SUFFIXES:
            field, origin = heightfield_from_mesh(source, pitch_mm), "mesh tile's top surface"
        else:
            heights, px, py, _ = _load_corrected(source, width_mm, depth_mm, pitch_mm, False, flatten)
            field = HeightField(heights, px, py)
        n_ior = design_ior if ior is None else ior
        rho = design_albedo if body_albedo is None else body_albedo
        if not (1.0 <= n_ior <= 3.0):
            raise PrintappError(f"--ior: expected a refractive index in [1, 3], got {n_ior:g}")
        if not (0.0 <= rho <= 1.0):
            raise PrintappError(f"--body-albedo: expected a value in [0, 1], got {rho:g}")
        target = design_lobe_error if lobe_error is None else lobe_error
        if target is not None and not (0.0 < target < 1.0):
            raise PrintappError(f"--lobe-error: expected a fraction in (0, 1), e.g. 0.01, got {target:g}")
        predicted = predict_appearance(
            field,
            ior=n_ior,
            body_albedo=rho,
            incident_deg=incident,
            rays=rays,
            n_theta=theta_bins,
            n_phi=phi_bins,
            seed=seed,
            periodic=periodic,
            distribution=distribution.value,
            lobe_error_target=target,
            max_rays=max_rays,
        )
        outputs = [(out, npz_bytes(brdf_arrays(predicted)))]
        metrics = {"source": str(source), "from": origin, "grid": list(field.shape), **predicted.metrics}
        if json_out is not None:
            outputs.append((json_out, (json.dumps(metrics, indent=2) + "\n").encode()))
        if plot is not None:
            outputs.append((plot, brdf_plot_png(predicted, source.name)))
        atomic_write_files(outputs)
    except PrintappError as exc:
        raise _fail(exc) from None
    m = predicted.metrics
    fit, hl = m["fit"], m["highlight"]
    spike = f", {fit['spike_weight']:.0%} of it in a mirror-sharp spike" if fit["spike_weight"] > 0 else ""
    _out.print(
        f"{source.name} ({origin}, {field.shape[1]} x {field.shape[0]} samples): albedo "
        f"{m['albedo'][0]:.3f} at normal incidence; gloss {m['gloss_gu']['20']:.1f} / "
        f"{m['gloss_gu']['60']:.1f} / {m['gloss_gu']['85']:.1f} GU at 20/60/85 deg, haze {m['haze']:.1f}; "
        f"highlight anisotropy {hl['anisotropy']:.2f} along {hl['azimuth_deg']:.0f} deg"
    )
    _out.print(
        f"fitted {fit['distribution']}: alpha {fit['alpha_u']:.3g} x {fit['alpha_v']:.3g} along "
        f"{fit['azimuth_deg']:.0f} deg{spike}, body albedo {fit['body_albedo']:.3f}; relative error "
        f"{_percent(fit['relative_error'])} over {fit['bins']} bins (the table's own noise there: "
        f"{_percent(fit['table_noise'])})"
    )
    errors = ", ".join(_percent(e) for e in m["lobe_error"])
    rays_used = m["rays_per_direction"]
    low, high = min(rays_used), max(rays_used)
    budget = f"{low:,}" if low == high else f"{low:,} to {high:,}"
    _out.print(f"reflection lobe's standard error per direction: {errors} ({budget} rays per direction)")
    for path in (out, plot, json_out):
        if path is not None:
            _out.print(f"  wrote {path}")


@app.command("material")
def material_command(
    material: Annotated[
        str, typer.Argument(help="A catalogue material (white-resin, milk, ...) or a material .toml file.")
    ],
    param: Annotated[
        list[str] | None, typer.Option("--param", "-p", help="Set a parameter, NAME=VALUE (repeatable).")
    ] = None,
    wavelengths_nm: Annotated[
        str | None, typer.Option(help="Comma-separated wavelengths (nm) [the material's own samples].")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON instead of tables.")] = False,
    plot: Annotated[
        Path | None, typer.Option("--plot", help="Write spectra and phase functions to this PNG.")
    ] = None,
) -> None:
    """Optical properties of a material from its particles (Lorenz-Mie): sigma_s, sigma_a, g, in RGB too."""
    import json
    import math

    from rich.table import Table

    from printapp.exporters import atomic_write_bytes
    from printapp.materials import material_plot_png, material_report

    try:
        values: dict[str, float] = {}
        for item in param or []:
            key, sep, text = item.partition("=")
            try:
                number = float(text)
            except ValueError:
                number = math.nan
            if not sep or not key or not math.isfinite(number):
                raise PrintappError(f"--param: expected NAME=VALUE with a finite number, got '{item}'")
            values[key.strip()] = number
        lam = None
        if wavelengths_nm is not None:
            try:
                lam = [float(v) for v in wavelengths_nm.split(",")]
            except ValueError:
                raise PrintappError(
                    f"--wavelengths-nm: expected comma-separated numbers, got '{wavelengths_nm}'"
                ) from None
            increasing = all(b > a for a, b in zip(lam, lam[1:], strict=False))
            if not increasing or any(not (math.isfinite(v) and v > 0) for v in lam):
                raise PrintappError(
                    f"--wavelengths-nm: expected increasing positive wavelengths, got '{wavelengths_nm}'"
                )
        if plot is not None and plot.suffix.lower() != ".png":
            raise PrintappError(f"{plot}: expected a plot file ending in .png")
        report, optics = material_report(material, values, lam)
        if plot is not None:
            atomic_write_bytes(plot, material_plot_png(report, optics))
    except PrintappError as exc:
        raise _fail(exc) from None
    if as_json:
        typer.echo(json.dumps(report, indent=2))
        return
    spectral = report["spectral"]
    table = Table(
        "wavelength nm",
        "host n",
        "sigma_s 1/mm",
        "sigma_a 1/mm",
        "sigma_t 1/mm",
        "g",
        "sigma_s' 1/mm",
        "transport mfp mm",
        title=f"{report['material']}: {report['description']}",
    )
    for k, lam_k in enumerate(spectral["wavelength_nm"]):
        table.add_row(
            f"{lam_k:g}",
            f"{spectral['host_n'][k]:.4f}",
            f"{spectral['sigma_s_per_mm'][k]:.5g}",
            f"{spectral['sigma_a_per_mm'][k]:.4g}",
            f"{spectral['sigma_t_per_mm'][k]:.5g}",
            f"{spectral['g'][k]:.4f}",
            f"{spectral['reduced_scattering_per_mm'][k]:.5g}",
            f"{spectral['transport_mfp_mm'][k]:.4g}",
        )
    _out.print(table)
    rgb = report["rgb"]

    def triple(values_: list, fmt: str) -> str:
        return ", ".join("inf" if v is None else format(v, fmt) for v in values_)

    parameters = ", ".join(f"{k} = {v:g}" for k, v in report["parameters"].items()) or "none"
    _out.print(f"parameters: {parameters}")
    _out.print(
        f"linear RGB: sigma_s ({triple(rgb['sigma_s_per_mm'], '.5g')}) 1/mm, "
        f"sigma_a ({triple(rgb['sigma_a_per_mm'], '.4g')}) 1/mm, g {rgb['g']:.4f}, "
        f"transport mfp ({triple(rgb['transport_mfp_mm'], '.4g')}) mm"
    )
    _out.print(
        f"body albedo ({triple(rgb['body_albedo'], '.4f')}), refractive index {rgb['refractive_index']:.4f}"
    )
    for source in report["sources"]:
        _out.print(f"source: {source}")
    if plot is not None:
        _out.print(f"wrote {plot}")


class RenderMode(StrEnum):
    auto = "auto"
    model = "model"
    table = "table"
    geometry = "geometry"


@app.command()
def render(
    design_file: Annotated[Path, typer.Argument(help="Design file (TOML).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="The image to write (.png).")] = Path("render.png"),
    spp: Annotated[int | None, typer.Option(min=1, max=65536, help="Samples per pixel [design's].")] = None,
    mode: Annotated[
        RenderMode, typer.Option(help="Relief as its fitted BRDF, its traced table, or geometry.")
    ] = RenderMode.auto,
    distance_scale: Annotated[
        float | None, typer.Option(min=0.2, max=1000.0, help="Camera distance, 1 = framing [design's].")
    ] = None,
    sweep: Annotated[
        Path | None, typer.Option(help="Also write a light-sweep strip (.png): the light circles the object.")
    ] = None,
) -> None:
    """Path-trace a design's predicted appearance, with the representation the camera needs."""
    from PIL import Image

    from printapp.design import load_design
    from printapp.exporters import atomic_write_files
    from printapp.mesh import combine_solids
    from printapp.pipeline import appearance_field, build_relief
    from printapp.rendering import light_sweep, predict_for_design, render_preview
    from render.mitsuba_adapter import to_srgb8

    def png_bytes(image) -> bytes:
        import io

        buffer = io.BytesIO()
        Image.fromarray(to_srgb8(image)).save(buffer, format="png", optimize=False, compress_level=6)
        return buffer.getvalue()

    try:
        for path in (out, sweep):
            if path is not None and path.suffix.lower() != ".png":
                raise PrintappError(f"{path}: expected an image file ending in .png")
        design = load_design(design_file)
        updates = {"mode": mode.value}
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
        outputs = [(out, png_bytes(preview.image))]
        if sweep is not None:
            outputs.append((sweep, png_bytes(light_sweep(design, relief, mesh, predicted, field))))
        atomic_write_files(outputs)
    except PrintappError as exc:
        raise _fail(exc) from None
    if preview.warning:
        _err.print(f"warning: {preview.warning}")
    _out.print(f"{design.name}: rendered as {preview.mode} ({preview.reason}) on {preview.variant}")
    for path in (out, sweep):
        if path is not None:
            _out.print(f"  wrote {path}")


@app.command()
def preview(
    model: Annotated[Path, typer.Argument(help="Any mesh (.stl .ply .obj .3mf .off).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="The image to write (.png).")] = Path("view.png"),
    width_px: Annotated[int, typer.Option(min=16, max=4096)] = 800,
    height_px: Annotated[int, typer.Option(min=16, max=4096)] = 600,
) -> None:
    """A quick off-screen look at any mesh (pyvista, no path tracing)."""
    from printapp.viewer import quick_view

    try:
        if out.suffix.lower() != ".png":
            raise PrintappError(f"{out}: expected an image file ending in .png")
        faces = quick_view(model, out, width_px, height_px)
    except PrintappError as exc:
        raise _fail(exc) from None
    _out.print(f"{model.name}: {faces:,} triangles; wrote {out}")


class FitModel(StrEnum):
    auto = "auto"
    fbm = "fbm"
    turbulence = "turbulence"
    marble = "marble"


@app.command()
def fit(
    image: Annotated[Path, typer.Argument(help="A photo (PNG, JPEG, WebP, TIFF...) of at least 32 x 32 px.")],
    out: Annotated[
        Path, typer.Option("--out", "-o", help="The design fragment to write (TOML, a texture table).")
    ] = Path("fitted.toml"),
    model: Annotated[FitModel, typer.Option(help="Model to fit; auto keeps the best score.")] = FitModel.auto,
    scale_mm_per_px: Annotated[
        float | None, typer.Option(help="Millimetres per photo pixel (default: the photo is 20 mm wide).")
    ] = None,
    preview: Annotated[
        Path | None, typer.Option(help="Write the photo and the synthesis side by side (.png).")
    ] = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write model, parameters and quality measures (.json).")
    ] = None,
    seed: Annotated[
        int, typer.Option(min=0, help="Seed of the noise, the optimiser's scan and baselines.")
    ] = 0,
    budget: Annotated[int, typer.Option(min=8, max=100000, help="Optimiser evaluations per model.")] = 160,
    size: Annotated[
        int, typer.Option(min=32, max=4096, help="Longer side the photo is analysed at (px).")
    ] = 512,
    quiet: QuietOption = False,
) -> None:
    """Fit procedural noise (fBm, turbulence, veined marble) to a photo, and say how close it comes.

    Writes a design fragment that `printapp design` prints and `printapp texture --from`
    renders; --preview puts photo and synthesis side by side; --json holds the parameters
    and the quality measures beside two baselines (random parameters, random phase).
    """
    from rich.table import Table

    from printapp.fit import fit_photo, write_outputs
    from printapp.progress import StageTimer

    try:
        if out.suffix.lower() != ".toml":
            raise PrintappError(f"{out}: expected an output file ending in .toml")
        if preview is not None and preview.suffix.lower() != ".png":
            raise PrintappError(f"{preview}: expected a preview file ending in .png")
        if json_out is not None and json_out.suffix.lower() != ".json":
            raise PrintappError(f"{json_out}: expected a metrics file ending in .json")
        with StageTimer(quiet=quiet) as timer:
            result = fit_photo(
                image,
                model=model.value,
                scale_mm_per_px=scale_mm_per_px,
                seed=seed,
                budget=budget,
                max_side=size,
                timer=timer,
            )
        written = write_outputs(result, out, preview, json_out)
    except PrintappError as exc:
        raise _fail(exc) from None
    metrics = result.metrics()
    table = Table(
        "measure",
        "fit",
        "random parameters",
        "random phase",
        "photo halves",
        title=(
            f"{image.name}: {metrics['model']} fit, score {metrics['score']:.2f} ({result.seconds:.1f} s)"
        ),
    )
    measures = metrics["measures"]
    for key in ("log_spectrum_distance", "wasserstein", "glcm_difference"):
        table.add_row(
            key,
            *(
                f"{measures[k][key]:.4g}"
                for k in ("fit", "random_parameters", "random_phase", "photo_halves")
            ),
        )
    _out.print(table)
    params = {k: v for k, v in metrics["params"].items() if k not in ("palette", "palette_range")}
    _out.print(", ".join(f"{k} {v}" for k, v in params.items()))
    if len(metrics["models"]) > 1:
        _out.print("scores: " + ", ".join(f"{k} {v['score']:.2f}" for k, v in metrics["models"].items()))
    for warning in result.warnings:
        _err.print(f"[bold yellow]warning:[/] {warning}", markup=True)
    for path in written:
        _out.print(f"  wrote {path}")


@app.command()
def bench(
    stages: Annotated[list[str] | None, typer.Argument(help="Stages to run [default: all].")] = None,
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder for bench.json and charts.")] = Path(
        "bench-out"
    ),
    repeats: Annotated[int, typer.Option(min=1, max=100, help="Timed repeats per setting (median).")] = 5,
) -> None:
    """Measure speed against accuracy; print a table, write JSON and PNG charts."""
    from printapp.bench import STAGES, run_bench

    try:
        names = list(stages) if stages else list(STAGES)
        results = run_bench(names, out, repeats=repeats, console=_out)
    except PrintappError as exc:
        raise _fail(exc) from None
    for path in results:
        _out.print(f"  wrote {path}")


def main() -> None:
    """Console-script entry point."""
    try:
        app()
    except KeyboardInterrupt:
        _err.print("interrupted; no partial outputs were left")
        sys.exit(130)

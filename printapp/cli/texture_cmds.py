"""``printapp texture`` and ``printapp fit``: texture images, and noise fitted to photos."""

import math
from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer

from printapp.cli.app import QuietOption, app, out, warn, wrote
from printapp.errors import PrintappError
from printapp.texture_kinds import TEXTURE_KIND_NAMES

TextureKind = StrEnum("TextureKind", {name: name for name in TEXTURE_KIND_NAMES})


@app.command()
def texture(
    out_path: Annotated[
        Path, typer.Option("--out", "-o", help="Output: .png (8-bit grey) or .npy (raw float64).")
    ],
    kind: Annotated[
        TextureKind | None, typer.Argument(help=f"{', '.join(TEXTURE_KIND_NAMES)} (or --from).")
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
    low: Annotated[int, typer.Option(min=0, help="turbulence, marble: first octave.")] = 0,
    high: Annotated[int, typer.Option(min=0, help="turbulence, marble: last octave.")] = 4,
    vein_angle_deg: Annotated[float, typer.Option(help="marble: direction the veins run (degrees).")] = 0.0,
    vein_period: Annotated[float, typer.Option(help="marble: distance between veins (noise cells).")] = 2.5,
    turbulence_strength: Annotated[
        float, typer.Option(help="marble: radians of phase per unit of turbulence.")
    ] = 5.0,
    sharpness: Annotated[
        float, typer.Option(help="marble: exponent (>= 1); large values, thin veins.")
    ] = 1.0,
    field: Annotated[
        str, typer.Option(help="lic: 'constant:ANGLE' (degrees), 'swirl' or 'image:FILE' (angle map).")
    ] = "swirl",
    length: Annotated[float, typer.Option(help="lic: streamline half-length (pixels).")] = 15.0,
) -> None:
    """Write a texture image: sparse convolution noise, fBm, turbulence, veined marble, or LIC along a field.

    PNG images are scaled from their minimum to their maximum (marble: its [0, 1] value);
    .npy files hold the raw values. The kinds are those of a design's [texture] table;
    lic convolves sparse convolution noise (2-pixel features unless --cells says
    otherwise) along the streamlines of --field. With --from FILE, the texture of a design
    (or of a fragment written by `printapp fit`) on a square of --width-mm, coloured by its
    palette; .npy then holds its values.
    """
    from printapp.outputs import atomic_write_bytes
    from printapp.texture import grey_png_bytes, texture_image, write_texture_from_file
    from printapp.texture_kinds import texture_kind

    suffix = out_path.suffix.lower()
    if suffix not in (".png", ".npy"):
        raise PrintappError(f"{out_path}: expected an output file ending in .png or .npy")
    if from_file is not None or kind is None:
        if kind is not None:
            raise PrintappError(f"give either KIND ({kind.value}) or --from FILE, not both")
        if from_file is None:
            raise PrintappError(f"expected a texture KIND ({', '.join(TEXTURE_KIND_NAMES)}) or --from")
        out.print(write_texture_from_file(from_file, out_path, size, width_mm))
        return
    cells_ = cells if cells is not None else (size / 2.0 if kind.value == "lic" else 8.0)
    values = texture_image(
        kind.value,
        size,
        cells_,
        {
            "seed": seed,
            "impulses": impulses,
            "cell_seed": cell_seed,
            "octaves": octaves,
            "lacunarity": lacunarity,
            "H": hurst,
            "low": low,
            "high": high,
            "vein_angle_rad": math.radians(vein_angle_deg),
            "vein_period_mm": vein_period * size / cells_,
            "turbulence_strength": turbulence_strength,
            "vein_sharpness": sharpness,
            "field": field,
            "length_mm": length,
        },
    )
    if suffix == ".npy":
        import io

        import numpy as np

        buffer = io.BytesIO()
        np.save(buffer, values)
        atomic_write_bytes(out_path, buffer.getvalue())
    else:
        atomic_write_bytes(out_path, grey_png_bytes(values, texture_kind(kind.value).unit_range))
    out.print(
        f"{kind.value}: {size}x{size}, mean {values.mean():.4f}, std {values.std():.4f}; wrote {out_path}"
    )


FitModel = StrEnum("FitModel", {name: name for name in ("auto", "fbm", "turbulence", "marble", "veined")})


@app.command()
def fit(
    image: Annotated[
        Path,
        typer.Argument(
            help="A photo (PNG, JPEG, WebP, TIFF...) of at least 32 x 32 px, or a measured height map "
            "(.al3d, .x3p, .gwy; .npy with --pitch-mm)."
        ),
    ],
    out_path: Annotated[
        Path, typer.Option("--out", "-o", help="The design fragment to write (TOML, a texture table).")
    ] = Path("fitted.toml"),
    model: Annotated[FitModel, typer.Option(help="Model to fit; auto keeps the best score.")] = FitModel.auto,
    scale_mm_per_px: Annotated[
        float | None, typer.Option(help="Millimetres per photo pixel (default: the photo is 20 mm wide).")
    ] = None,
    pitch_mm: Annotated[
        float | None, typer.Option(help="Height maps in .npy: the sample spacing (mm; heights in mm).")
    ] = None,
    magnify: Annotated[
        float | None,
        typer.Option(min=1e-6, help="Height maps: magnify the relief (default: up to the printer's pixel)."),
    ] = None,
    preview: Annotated[
        Path | None, typer.Option(help="Write the photo and the synthesis side by side (.png).")
    ] = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write model, parameters and quality measures (.json).")
    ] = None,
    seed: Annotated[int, typer.Option(min=0, help="Seed of the noise (the optimiser's is fixed).")] = 0,
    budget: Annotated[
        int | None, typer.Option(min=8, max=100000, help="Coarse evaluations per synthesised model.")
    ] = None,
    size: Annotated[
        int, typer.Option(min=32, max=4096, help="Longer side the photo is analysed at (px).")
    ] = 512,
    workers: Annotated[
        int | None, typer.Option(min=1, max=64, help="Threads for the search (default: the cores).")
    ] = None,
    quiet: QuietOption = False,
) -> None:
    """Fit a printable texture (fBm, turbulence, marble, branching veins) to a photo or a measured surface.

    Writes a design fragment that `printapp design` prints and `printapp texture --from`
    renders; --preview puts photo and synthesis side by side; --json holds the parameters
    and each quality measure as a ratio to the photo's own variation, beside the
    random-phase baseline.
    """
    from printapp.fit_outputs import fit_any
    from printapp.progress import StageTimer

    with StageTimer(quiet=quiet) as timer:
        lines, warnings, written = fit_any(
            image,
            out_path,
            preview=preview,
            json_out=json_out,
            model=model.value,
            scale_mm_per_px=scale_mm_per_px,
            pitch_mm=pitch_mm,
            seed=seed,
            budget=budget,
            size=size,
            workers=workers,
            magnify=magnify,
            timer=timer,
        )
    for line in lines:
        out.print(line)
    for message in warnings:
        warn(message)
    wrote(written)

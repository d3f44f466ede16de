"""What ``printapp fit`` writes: the design fragment, the side-by-side preview, the metrics; and the
one application function the command calls, for photos and for measured surfaces alike.
"""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

import numpy as np

from printapp.errors import PrintappError
from printapp.fit import FitResult

HEIGHTMAP_SUFFIXES = (".al3d", ".x3p", ".gwy", ".npy")
"""Files ``printapp fit`` reads as measured surfaces (heights), not as photos."""
COMMON_KEYS = ("stretch", "angle_rad")
"""Keys every kind reads; the fragment carries them when they are not their defaults."""


def fragment_keys(texture) -> list[str]:
    """The ``[texture]`` keys a fragment writes for ``texture``."""
    from printapp.design import Texture
    from printapp.texture_kinds import texture_kind

    defaults = Texture()
    common = [k for k in COMMON_KEYS if getattr(texture, k) != getattr(defaults, k)]
    return ["kind", "feature_size_mm", "seed", *texture_kind(texture.kind).parameters, *common]


def texture_toml(texture, header: list[str]) -> str:
    """A fragment: comment lines, then the texture's [texture] table in file units."""
    import tomli_w

    from printapp.design_io import to_file_units

    dumped = texture.model_dump(mode="python")
    names = [*fragment_keys(texture), "palette", "palette_range", "palette_values"]
    data = to_file_units({k: dumped[k] for k in names if k in dumped})
    return "\n".join([*header, ""]) + tomli_w.dumps({"texture": data})


def fitted_toml(result: FitResult) -> str:
    """The design fragment: a [texture] table that `printapp design` and `printapp texture --from` read."""
    w_mm = result.photo.analysed_px[0] * result.scale_mm_per_px * result.photo.downscale
    header = [
        f"# printapp fit: {result.chosen.name} fitted to {Path(result.photo.path).name}",
        f"# ({result.photo.original_px[0]} x {result.photo.original_px[1]} px at "
        f"{result.scale_mm_per_px:.6g} mm/px: the photo spans {w_mm:.6g} mm), score {result.score:.2f}",
        "# measures against the photo's own variation (1 = as close as its halves are to each other): "
        + ", ".join(f"{k} {v:.2f}" for k, v in result.chosen.ratios.items()),
        *(f"# warning: {w}" for w in result.warnings),
        "# Print it:   printapp design THIS_FILE   (a 20 mm tile with the defaults), or",
        '#             [texture] from = "THIS_FILE" in your own design (keys beside it override;',
        '#             veins = "sunk" cuts the veins in, "raised" stands them up).',
        f"# Preview:    printapp texture --from THIS_FILE --width-mm {w_mm:.6g} "
        f"--size {result.photo.analysed_px[0]} -o preview.png",
    ]
    return texture_toml(result.chosen.texture, header)


def side_by_side(images: list[np.ndarray], labels: list[str]) -> bytes:
    """Images (rows upwards, RGB in [0, 1], same height) side by side with captions, as PNG bytes."""
    from PIL import Image, ImageDraw

    gap, caption = 8, 18
    tiles = [_to_image(rgb) for rgb in images]
    h = max(t.size[1] for t in tiles)
    width = sum(t.size[0] for t in tiles) + gap * (len(tiles) - 1)
    canvas = Image.new("RGB", (width, h + caption), (255, 255, 255))
    draw = ImageDraw.Draw(canvas)
    x = 0
    for tile, label in zip(tiles, labels, strict=True):
        canvas.paste(tile, (x, caption))
        draw.text((x + 4, 3), label, fill=(0, 0, 0))
        x += tile.size[0] + gap
    buffer = io.BytesIO()
    canvas.save(buffer, format="PNG")
    return buffer.getvalue()


def preview_png(result: FitResult) -> bytes:
    """The photo and the fitted synthesis side by side, with a caption."""
    return side_by_side(
        [result.photo.rgb, result.chosen.rgb],
        ["photo", f"{result.chosen.name} fit, score {result.score:.2f}"],
    )


def _to_image(rgb: np.ndarray):
    from PIL import Image

    if rgb.ndim == 2:
        rgb = np.repeat(rgb[..., None], 3, axis=-1)
    return Image.fromarray(np.round(np.clip(rgb[::-1], 0.0, 1.0) * 255).astype(np.uint8), mode="RGB")


def write_outputs(
    result: FitResult, toml_path: Path, preview_path: Path | None = None, json_path: Path | None = None
) -> list[Path]:
    """Write fitted.toml (and fit.png, metrics.json): all written first, then renamed into place."""
    import json

    from printapp.outputs import atomic_write_files

    outputs: list[tuple[Path, bytes]] = [(toml_path, fitted_toml(result).encode())]
    if preview_path is not None:
        outputs.append((preview_path, preview_png(result)))
    if json_path is not None:
        outputs.append((json_path, (json.dumps(result.metrics(), indent=2) + "\n").encode()))
    return atomic_write_files(outputs)


def surface_toml(surface) -> str:
    """A measured surface's fragment: [base], [relief] and [texture] that print the look-alike relief."""
    import tomli_w

    from printapp.design_io import to_file_units

    design = surface.design
    m, f = surface.measured, surface.fitted
    header = [
        f"# printapp fit: an fBm relief with the ISO 25178 statistics of {Path(surface.path).name}",
        f"# ({surface.heights_mm.shape[1]} x {surface.heights_mm.shape[0]} samples at "
        f"{surface.pitch_mm * 1000:.6g} µm): measured -> fitted",
        f"#   Sq {m.sq_um:.4g} -> {f.sq_um:.4g} µm, Sdq {m.sdq:.4g} -> {f.sdq:.4g}, "
        f"Sal {m.sal_um:.4g} -> {f.sal_um:.4g} µm, Str {m.str_ratio:.3g} -> {f.str_ratio:.3g}, "
        f"Std {m.std_deg:.4g} -> {f.std_deg:.4g} deg",
        *(f"# warning: {w}" for w in surface.warnings),
        f"# The relief below is the fitted one magnified {surface.magnification:g} times (lengths and",
        "# heights: Sq and Sal grow by that factor, the slopes (Sdq), and so the gloss, stay).",
        "# Print it:   printapp design THIS_FILE; to change the magnification, multiply width_mm, depth_mm,",
        "#             pitch_mm, amplitude_mm and feature_size_mm by the same factor.",
        '#             [texture] from = "THIS_FILE" takes the texture alone.',
        "",
    ]
    texture = design.texture.model_dump(mode="python")
    data = {
        "base": {k: getattr(design.base, k) for k in ("shape", "width_mm", "depth_mm")},
        "relief": {"amplitude_mm": design.relief.amplitude_mm, "pitch_mm": design.relief.pitch_mm},
        "texture": {k: texture[k] for k in fragment_keys(design.texture)},
    }
    return "\n".join(header) + tomli_w.dumps(to_file_units(data))


def surface_preview_png(surface) -> bytes:
    """The measured heights and the fitted relief side by side (grey, each from its minimum to maximum)."""

    def grey(z: np.ndarray) -> np.ndarray:
        span = float(np.ptp(z)) or 1.0
        return np.repeat(((z - z.min()) / span)[..., None], 3, axis=-1)

    return side_by_side(
        [grey(surface.heights_mm), grey(surface.relief_mm)],
        ["measured heights", f"fitted fBm relief, Sq {surface.fitted.sq_um:.3g} um"],
    )


def write_surface_outputs(
    surface, toml_path: Path, preview_path: Path | None = None, json_path: Path | None = None
) -> list[Path]:
    """Write a surface's fragment (and preview, metrics): all written first, then renamed into place."""
    import json

    from printapp.outputs import atomic_write_files

    outputs: list[tuple[Path, bytes]] = [(toml_path, surface_toml(surface).encode())]
    if preview_path is not None:
        outputs.append((preview_path, surface_preview_png(surface)))
    if json_path is not None:
        outputs.append((json_path, (json.dumps(surface.metrics(), indent=2) + "\n").encode()))
    return atomic_write_files(outputs)


def summary_table(result: FitResult):
    """A Rich table: each measure as a ratio to the photo's own variation, fit beside random phase."""
    from rich.table import Table

    metrics = result.metrics()
    table = Table(
        "measure",
        "fit",
        "random phase",
        "fit ratio",
        "random-phase ratio",
        title=f"{Path(result.photo.path).name}: {metrics['model']} fit, score {metrics['score']:.2f} "
        f"({result.seconds:.1f} s); ratio 1 = as close as the photo's halves",
    )
    m, r = metrics["measures"], metrics["ratios"]
    for key in m["fit"]:
        table.add_row(
            key,
            f"{m['fit'][key]:.4g}",
            f"{m['random_phase'][key]:.4g}",
            f"{r['fit'][key]:.2f}",
            f"{r['random_phase'][key]:.2f}",
        )
    return table


def _check_outputs(out_path: Path, preview: Path | None, json_out: Path | None) -> None:
    if out_path.suffix.lower() != ".toml":
        raise PrintappError(f"{out_path}: expected an output file ending in .toml")
    if preview is not None and preview.suffix.lower() != ".png":
        raise PrintappError(f"{preview}: expected a preview file ending in .png")
    if json_out is not None and json_out.suffix.lower() != ".json":
        raise PrintappError(f"{json_out}: expected a metrics file ending in .json")


def fit_any(
    source: Path,
    out_path: Path,
    *,
    preview: Path | None = None,
    json_out: Path | None = None,
    model: str = "auto",
    scale_mm_per_px: float | None = None,
    pitch_mm: float | None = None,
    seed: int = 0,
    budget: int | None = None,
    size: int = 512,
    workers: int | None = None,
    magnify: float | None = None,
    timer=None,
) -> tuple[list[Any], list[str], list[Path]]:
    """``printapp fit`` on a photo or a height map (by its suffix): (lines to print, warnings, files written).

    Raises
    ------
    PrintappError
        For bad files or options (one sentence naming them).
    """
    _check_outputs(out_path, preview, json_out)
    if source.suffix.lower() in HEIGHTMAP_SUFFIXES:
        from printapp.fit_surface import fit_surface

        if model not in ("auto", "fbm"):
            raise PrintappError(f"--model: a measured surface is fitted by fbm (or auto), got '{model}'")
        if scale_mm_per_px is not None:
            raise PrintappError(
                "--scale-mm-per-px: a height map carries its own pitch (give --pitch-mm for .npy)"
            )
        surface = fit_surface(
            source, pitch_mm=pitch_mm, seed=seed, max_side=size, magnify=magnify, timer=timer
        )
        written = write_surface_outputs(surface, out_path, preview, json_out)
        return surface.summary_lines(), surface.warnings, written
    if pitch_mm is not None:
        raise PrintappError(
            f"--pitch-mm: only for height maps ({', '.join(HEIGHTMAP_SUFFIXES)}), not {source.name}"
        )
    from printapp.fit import DEFAULT_BUDGET, fit_photo

    result = fit_photo(
        source,
        model=model,
        scale_mm_per_px=scale_mm_per_px,
        seed=seed,
        budget=DEFAULT_BUDGET if budget is None else budget,
        max_side=size,
        workers=workers,
        timer=timer,
    )
    written = write_outputs(result, out_path, preview, json_out)
    params = {k: v for k, v in result.metrics()["params"].items() if k not in ("palette", "palette_values")}
    lines: list[Any] = [summary_table(result), ", ".join(f"{k} {_short(v)}" for k, v in params.items())]
    if len(result.reports) > 1:
        lines.append("scores: " + ", ".join(f"{k} {r.score:.2f}" for k, r in result.reports.items()))
    return lines, result.warnings, written


def _short(value: Any) -> str:
    if isinstance(value, float) and math.isfinite(value):
        return f"{value:.4g}"
    return str(value)

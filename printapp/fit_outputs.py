"""What ``printapp fit`` writes: the design fragment, the side-by-side preview, the metrics."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from printapp.fit import FitResult


def fitted_toml(result: FitResult) -> str:
    """The design fragment: a [texture] table that `printapp design` and `printapp texture --from` read."""
    import tomli_w

    from printapp.design import to_file_units
    from printapp.texture_kinds import texture_kind

    texture = result.chosen.texture
    dumped = texture.model_dump(mode="python")
    names = [
        "kind",
        "feature_size_mm",
        "seed",
        *texture_kind(texture.kind).parameters,
        "palette",
        "palette_range",
    ]
    data = to_file_units({k: dumped[k] for k in names})
    w_mm = result.photo.analysed_px[0] * result.scale_mm_per_px * result.photo.downscale
    lines = [
        f"# printapp fit: {result.chosen.name} fitted to {Path(result.photo.path).name}",
        f"# ({result.photo.original_px[0]} x {result.photo.original_px[1]} px at "
        f"{result.scale_mm_per_px:.6g} mm/px: the photo spans {w_mm:.6g} mm), score {result.score:.2f}",
    ]
    lines += [f"# warning: {w}" for w in result.warnings]
    lines += [
        "# Print it:   printapp design THIS_FILE   (a 20 mm tile with the defaults), or",
        '#             [texture] from = "THIS_FILE" in your own design (keys beside it override).',
        f"# Preview:    printapp texture --from THIS_FILE --width-mm {w_mm:.6g} "
        f"--size {result.photo.analysed_px[0]} -o preview.png",
        "",
    ]
    return "\n".join(lines) + tomli_w.dumps({"texture": data})


def preview_png(result: FitResult) -> bytes:
    """The photo and the fitted synthesis side by side, with a caption."""
    from PIL import Image, ImageDraw

    photo = _to_image(result.photo.rgb)
    synth = _to_image(result.chosen.rgb)
    gap = 8
    caption = 18
    w, h = photo.size
    canvas = Image.new("RGB", (2 * w + gap, h + caption), (255, 255, 255))
    canvas.paste(photo, (0, caption))
    canvas.paste(synth, (w + gap, caption))
    draw = ImageDraw.Draw(canvas)
    draw.text((4, 3), "photo", fill=(0, 0, 0))
    draw.text((w + gap + 4, 3), f"{result.chosen.name} fit, score {result.score:.2f}", fill=(0, 0, 0))
    buffer = io.BytesIO()
    canvas.save(buffer, format="PNG")
    return buffer.getvalue()


def _to_image(rgb: np.ndarray):
    from PIL import Image

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

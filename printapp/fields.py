"""Direction fields for line integral convolution on tiles and images, from a short spec.

``constant:ANGLE`` (degrees from +x towards +y), ``swirl`` (circles about the centre),
``image:FILE`` (an angle map: grey 0..255 is 0..180 degrees, an orientation field).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from printapp.errors import DesignError


def check_field_spec(spec: str) -> str:
    """Validate a field spec's form (not the file's content); return it unchanged."""
    kind, _, arg = spec.partition(":")
    if kind == "swirl" and not arg:
        return spec
    if kind == "constant":
        try:
            angle = float(arg)
        except ValueError:
            raise ValueError(f"expected 'constant:ANGLE' with ANGLE in degrees, got {spec!r}") from None
        if not math.isfinite(angle):
            raise ValueError(f"expected a finite angle, got {spec!r}")
        return spec
    if kind == "image" and arg:
        return spec
    raise ValueError(f"expected 'constant:ANGLE', 'swirl' or 'image:FILE', got {spec!r}")


def field_on_grid(
    spec: str, x: np.ndarray, y: np.ndarray, base_dir: Path | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Components (u along x, v along y) of the field ``spec`` on the grid x by y.

    Raises
    ------
    DesignError
        If an image field's file is missing or unreadable.
    """
    check_field_spec(spec)
    kind, _, arg = spec.partition(":")
    xx, yy = np.meshgrid(x, y)
    if kind == "constant":
        a = math.radians(float(arg))
        return np.full_like(xx, math.cos(a)), np.full_like(xx, math.sin(a))
    if kind == "swirl":
        cx = 0.5 * (x[0] + x[-1])
        cy = 0.5 * (y[0] + y[-1])
        return -(yy - cy), xx - cx
    from PIL import Image, UnidentifiedImageError

    path = Path(arg)
    if base_dir is not None and not path.is_absolute():
        path = base_dir / path
    try:
        with Image.open(path) as image:
            grey = np.asarray(
                image.convert("L").resize((len(x), len(y)), Image.Resampling.BILINEAR), dtype=float
            )
    except FileNotFoundError:
        raise DesignError(f"{path}: no such field image") from None
    except (UnidentifiedImageError, OSError) as exc:
        raise DesignError(f"{path}: cannot read the field image ({exc})") from None
    # Image rows run downwards; our y runs upwards.
    angle = grey[::-1] / 255.0 * math.pi
    return np.cos(angle), np.sin(angle)

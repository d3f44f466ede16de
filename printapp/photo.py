"""Photos for ``printapp fit``: read with EXIF orientation, converted to RGB or grey,
downsampled, reduced to luminance; and a palette of their colours ordered along luminance.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from printapp.errors import PrintappError

MIN_SIDE_PX = 32
"""Smallest image side accepted: fewer pixels hold too few features to fit anything."""
PALETTE_SIZE = 32
LUMA = np.array([0.2126, 0.7152, 0.0722])
"""Rec. 709 luminance weights, applied to the stored sRGB values."""


@dataclass
class Photo:
    """A photo ready to fit: colours and luminance in [0, 1], rows running upwards (y up)."""

    path: str
    rgb: np.ndarray
    lum: np.ndarray
    original_px: tuple[int, int]
    """(width, height) of the file, after EXIF orientation."""
    notes: list[str] = field(default_factory=list)

    @property
    def analysed_px(self) -> tuple[int, int]:
        return self.lum.shape[1], self.lum.shape[0]

    @property
    def downscale(self) -> float:
        """Original pixels per analysed pixel."""
        return self.original_px[0] / self.lum.shape[1]


def _refuse(path: Path, what: str) -> PrintappError:
    return PrintappError(f"{path}: {what}")


def read_photo(path: str | Path, max_side: int = 512) -> Photo:
    """Read an image file for fitting.

    EXIF orientation is applied; palette, bilevel, CMYK and other modes are converted to
    RGB or grey; 16-bit and 32-bit grey keep their precision; an alpha channel is
    dropped when every pixel is opaque. The image is downsampled (Pillow's Lanczos
    filter, in floating point) so that its longer side is at most ``max_side``.

    Raises
    ------
    PrintappError
        If the file is missing or unreadable, has transparent pixels, or is smaller than
        :data:`MIN_SIDE_PX` on a side.
    """
    from PIL import Image, ImageOps, UnidentifiedImageError

    path = Path(path)
    if not path.exists():
        raise _refuse(path, "no such image file")
    if path.is_dir():
        raise _refuse(path, "expected an image file, found a folder")
    notes: list[str] = []
    try:
        with Image.open(path) as opened:
            opened.load()
            orientation = opened.getexif().get(0x0112, 1)
            image = ImageOps.exif_transpose(opened)
            if orientation in range(2, 9):
                notes.append("EXIF orientation applied")
            image.load()
    except UnidentifiedImageError:
        raise _refuse(path, "cannot read the image; expected a PNG, JPEG, WebP, TIFF or BMP file") from None
    except Image.DecompressionBombError:
        raise _refuse(
            path, "the image is too large to open safely (Pillow's decompression-bomb limit)"
        ) from None
    except (OSError, SyntaxError, ValueError) as exc:
        raise _refuse(path, f"cannot read the image ({exc})") from None
    width, height = image.size
    if min(width, height) < MIN_SIDE_PX:
        raise _refuse(
            path, f"the image is {width} x {height} px; expected at least {MIN_SIDE_PX} px on each side"
        )
    try:
        channels = _channels(image, path, notes)
    except (ValueError, OSError) as exc:
        raise _refuse(path, f"cannot convert its {image.mode} pixels to RGB or grey ({exc})") from None
    factor = max(width, height) / max_side
    if factor > 1.0:
        size = (max(1, round(width / factor)), max(1, round(height / factor)))
        channels = [
            np.asarray(
                Image.fromarray(c.astype(np.float32), mode="F").resize(size, Image.Resampling.LANCZOS),
                dtype=np.float64,
            )
            for c in channels
        ]
    planes = np.clip(np.stack(channels, axis=-1), 0.0, 1.0)[::-1]  # rows upwards
    rgb = np.repeat(planes, 3, axis=-1) if planes.shape[-1] == 1 else planes
    return Photo(str(path), rgb, rgb @ LUMA, (width, height), notes)


def _channels(image, path: Path, notes: list[str]) -> list[np.ndarray]:
    """The image's colour channels as float arrays in [0, 1] (one for grey, three for colour)."""
    mode = image.mode
    if mode in ("P", "PA"):
        notes.append("palette image converted to RGB")
        image = image.convert("RGBA")
        mode = "RGBA"
    if mode in ("RGBA", "LA", "La", "RGBa"):
        alpha = np.asarray(image.getchannel("A"))
        if np.any(alpha < 255):
            raise _refuse(
                path,
                f"{np.count_nonzero(alpha < 255)} pixels are transparent; expected an opaque photo "
                "(flatten it onto a background first)",
            )
        notes.append("opaque alpha channel dropped")
        image = image.convert("RGB" if mode in ("RGBA", "RGBa") else "L")
        mode = image.mode
    if mode.startswith("I;16"):
        notes.append("16-bit grey")
        return [np.asarray(image, dtype=np.float64) / 65535.0]
    if mode == "I":
        values = np.asarray(image, dtype=np.float64)
        top = 65535.0 if values.max() <= 65535 else 4294967295.0
        notes.append("16-bit grey" if top == 65535.0 else "32-bit grey")
        return [values / top]
    if mode == "F":
        values = np.asarray(image, dtype=np.float64)
        if not np.all(np.isfinite(values)):
            raise _refuse(path, "the floating-point image has NaN or infinite pixels")
        top = float(values.max())
        return [values / top if top > 1.0 else values]
    if mode in ("1", "L"):
        return [np.asarray(image.convert("L"), dtype=np.float64) / 255.0]
    rgb = np.asarray(image.convert("RGB"), dtype=np.float64) / 255.0
    return [rgb[..., 0], rgb[..., 1], rgb[..., 2]]


# ---------------------------------------------------------------------------------------------
# Palette: the photo's colours ordered along luminance


def luminance_palette(photo: Photo, size: int = PALETTE_SIZE) -> tuple[np.ndarray, np.ndarray]:
    """The photo's mean colour at ``size`` luminances evenly spaced over its range.

    Pixels are binned by luminance; a bin's colour is the mean of its pixels, and empty
    bins are interpolated from their neighbours. Returns (luminance knots, (size, 3) colours).
    """
    lum = photo.lum.ravel()
    rgb = photo.rgb.reshape(-1, 3)
    lo, hi = float(lum.min()), float(lum.max())
    knots = np.linspace(lo, hi, size)
    if hi <= lo:
        return knots, np.repeat(rgb[:1], size, axis=0)
    which = np.clip(np.rint((lum - lo) / (hi - lo) * (size - 1)).astype(np.int64), 0, size - 1)
    counts = np.bincount(which, minlength=size)
    colours = np.empty((size, 3))
    filled = counts > 0
    for c in range(3):
        sums = np.bincount(which, weights=rgb[:, c], minlength=size)
        colours[filled, c] = sums[filled] / counts[filled]
        colours[~filled, c] = np.interp(knots[~filled], knots[filled], colours[filled, c])
    return knots, colours


def hex_colour(colour: np.ndarray) -> str:
    """An sRGB colour in [0, 1] as ``#rrggbb``."""
    r, g, b = (int(round(float(np.clip(v, 0.0, 1.0)) * 255)) for v in colour)
    return f"#{r:02x}{g:02x}{b:02x}"


# ---------------------------------------------------------------------------------------------
# The fit

"""The one input boundary: every file printapp reads is checked here before a library sees it.

A path must name a regular file (not a folder, a FIFO, ``/dev/zero`` or a socket), the
bytes read are bounded, images are opened with a pixel limit taken from the memory budget
(:mod:`printapp.memory`), and whatever a decoding library raises becomes one sentence
naming the file and what was expected (:class:`printapp.errors.DesignError`, exit 2).
"""

from __future__ import annotations

import os
import stat
import warnings
from pathlib import Path
from typing import Any

from printapp.errors import DesignError

TEXT_LIMIT_BYTES = 4 << 20
"""Largest TOML file (design, fragment, material library) read: 4 MB is far beyond any real one."""


def regular_file(path: str | Path, what: str) -> Path:
    """``path`` if it names a regular file; else one sentence saying what it is instead.

    ``what`` names the kind of file, e.g. ``"design"``, ``"mesh"``, ``"height map"``.
    """
    path = Path(path)
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise DesignError(f"{path}: no such {what} file") from None
    except NotADirectoryError:
        raise DesignError(f"{path}: no such {what} file (a part of the path is a file)") from None
    except OSError as exc:
        raise DesignError(f"{path}: cannot read the {what} file ({exc.strerror or exc})") from None
    if stat.S_ISDIR(mode):
        raise DesignError(f"{path}: expected a {what} file, found a folder")
    if not stat.S_ISREG(mode):
        raise DesignError(f"{path}: expected a regular {what} file, found a device, pipe or socket")
    return path


def read_bytes(path: str | Path, what: str, limit_bytes: int) -> bytes:
    """The bytes of a regular file of at most ``limit_bytes``.

    Raises
    ------
    DesignError
        If the path is not a regular file, is larger than the limit, or cannot be read.
    """
    path = regular_file(path, what)
    try:
        with open(path, "rb") as handle:
            data = handle.read(limit_bytes + 1)
    except OSError as exc:
        raise DesignError(f"{path}: cannot read the {what} file ({exc.strerror or exc})") from None
    if len(data) > limit_bytes:
        raise DesignError(
            f"{path}: the {what} file is larger than {limit_bytes:,} bytes; expected a smaller file"
        )
    return data


def read_text(path: str | Path, what: str, limit_bytes: int = TEXT_LIMIT_BYTES) -> str:
    """A UTF-8 text file (a leading byte-order mark is dropped), bounded as :func:`read_bytes`."""
    data = read_bytes(path, what, limit_bytes)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise DesignError(f"{path}: expected a UTF-8 text {what} file") from None
    return text.removeprefix("\ufeff")


def open_image(path: str | Path, what: str, max_pixels: int | None = None) -> Any:
    """Open an image with Pillow, refusing decompression bombs and unreadable files in one sentence.

    ``max_pixels`` defaults to what the memory budget holds at 16 bytes per pixel (the
    float64 copies a height map or photo goes through). The image is loaded before it
    is returned, so a truncated file fails here, not later.
    """
    from PIL import Image, UnidentifiedImageError

    from printapp.memory import budget_bytes, human

    path = regular_file(path, what)
    limit = max_pixels if max_pixels is not None else max(1, budget_bytes() // 16)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            previous = Image.MAX_IMAGE_PIXELS
            Image.MAX_IMAGE_PIXELS = limit
            try:
                image = Image.open(path)
                width, height = image.size
                if width * height > limit:
                    raise Image.DecompressionBombError("too many pixels")
                image.load()
            finally:
                Image.MAX_IMAGE_PIXELS = previous
    except (Image.DecompressionBombError, Image.DecompressionBombWarning):
        raise DesignError(
            f"{path}: the {what} image holds more pixels than the memory budget allows "
            f"({limit:,} pixels, {human(limit * 16)} as floats); expected a smaller image"
        ) from None
    except UnidentifiedImageError:
        raise DesignError(
            f"{path}: cannot read the {what} image; expected a PNG, JPEG, WebP or TIFF file"
        ) from None
    except (OSError, ValueError, SyntaxError, EOFError) as exc:
        raise DesignError(f"{path}: cannot read the {what} image ({exc})") from None
    return image

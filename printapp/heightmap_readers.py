"""Reading height maps with their physical scale, and refusing hostile ones in one sentence.

Formats: 8/16-bit PNG and TIFF images (grey level to height, with a physical width and
depth from the user), ``.npy`` (heights in mm, with a pitch), Alicona ``.al3d``, ISO
25178-72 ``.x3p`` and Gwyddion ``.gwy``. Heights come back in mm, missing data as NaN,
non-square pixels as they are.

Every header field is checked before it is used: sizes are positive integers that agree
with the bytes actually present, pitches are positive and finite, offsets lie inside the
file, and the decoded map must fit the memory budget (:mod:`printapp.memory`) *before*
it is decoded (the size a zip member or an ``.npy`` header declares is checked, not
trusted).
"""

from __future__ import annotations

import io
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from noise.heightfield import HeightField
from printapp.errors import DesignError
from printapp.inputs import open_image, read_bytes, regular_file
from printapp.memory import budget_bytes, require

IMAGE_SUFFIXES = (".png", ".tif", ".tiff")
SUFFIXES = (*IMAGE_SUFFIXES, ".npy", ".al3d", ".x3p", ".gwy")
BYTES_PER_SAMPLE = 48
"""What a height map costs once read: the float64 map and the copies correction makes."""
MAX_SIDE = 1 << 20
"""Largest sample count along one side any header may declare."""
MAX_HEIGHT_MM = 1e6
"""Largest height a map may hold (a kilometre): beyond it, squares and sums of heights overflow."""
MAX_PITCH_M = 1.0
"""Largest sample spacing a measured file may declare (1 m: no instrument's pixel is larger)."""


@dataclass(frozen=True)
class Topography:
    """Heights (mm; NaN where the instrument saw nothing) on a grid with its pitches (mm)."""

    heights_mm: np.ndarray
    pitch_x_mm: float
    pitch_y_mm: float

    def field(self) -> HeightField:
        """As a HeightField (requires every value to be finite; fill missing data first)."""
        return HeightField(self.heights_mm, self.pitch_x_mm, self.pitch_y_mm)


def _check_grid(path: Path, cols: int, rows: int, what: str) -> None:
    if not (2 <= cols <= MAX_SIDE and 2 <= rows <= MAX_SIDE):
        raise DesignError(
            f"{path}: {what} declares {cols} x {rows} samples; expected 2 to {MAX_SIDE} per side"
        )
    require(
        float(cols) * rows * BYTES_PER_SAMPLE,
        what=f"its {cols} x {rows}-sample height map",
        setting=str(path),
    )


def _check_pitch(path: Path, value: float, name: str) -> float:
    if not (math.isfinite(value) and 0.0 < value <= MAX_PITCH_M):
        raise DesignError(f"{path}: {name} is {value!r} m; expected a positive sample spacing up to 1 m")
    return value


def _read_al3d(path: Path) -> Topography:
    raw = read_bytes(path, "height map", max(1 << 20, budget_bytes() // 4))
    if not raw.startswith(b"AliconaImaging"):
        raise DesignError(f"{path}: not an Alicona .al3d file (no AliconaImaging header)")
    tags: dict[str, str] = {}
    count = 17
    for i in range(512):
        record = raw[17 + 52 * i : 17 + 52 * (i + 1)]
        if len(record) < 52 or i >= count:
            break
        key = record[:20].split(b"\0")[0].decode("latin-1")
        value = record[20:50].split(b"\0")[0].decode("latin-1", errors="replace")
        tags[key] = value
        if key == "TagCount":
            try:
                count = int(value)
            except ValueError:
                raise DesignError(f"{path}: .al3d TagCount is {value!r}; expected an integer") from None
    try:
        cols, rows = int(tags["Cols"]), int(tags["Rows"])
        offset = int(tags["DepthImageOffset"])
        px_m, py_m = float(tags["PixelSizeXMeter"]), float(tags["PixelSizeYMeter"])
        invalid = np.float32(float(tags.get("InvalidPixelValue", "nan")))
    except KeyError as exc:
        raise DesignError(f"{path}: .al3d header lacks {exc}") from None
    except (ValueError, OverflowError) as exc:
        raise DesignError(f"{path}: .al3d header has an unreadable value ({exc})") from None
    _check_grid(path, cols, rows, ".al3d")
    _check_pitch(path, px_m, "PixelSizeXMeter")
    _check_pitch(path, py_m, "PixelSizeYMeter")
    padded = (cols + 7) // 8 * 8  # rows are padded to a multiple of 8 columns
    if offset < 0 or offset + rows * padded * 4 > len(raw):
        raise DesignError(
            f"{path}: .al3d depth image ({rows} x {cols} at byte {offset}) lies outside the "
            f"{len(raw):,}-byte file; expected a complete file"
        )
    depth = np.frombuffer(raw, dtype="<f4", count=rows * padded, offset=offset).reshape(rows, padded)[
        :, :cols
    ]
    heights = np.where(depth == invalid, np.nan, depth.astype(np.float64)) * 1000.0
    return Topography(heights, px_m * 1000.0, py_m * 1000.0)


def _xml_text(path: Path, root: ElementTree.Element, parent_tag: str, tag: str) -> str:
    parent = next((e for e in root.iter() if e.tag.split("}")[-1] == parent_tag), None)
    node = None if parent is None else next((e for e in parent.iter() if e.tag.split("}")[-1] == tag), None)
    if node is None or node.text is None:
        raise DesignError(f"{path}: .x3p main.xml lacks {parent_tag}/{tag}")
    return node.text.strip()


def _member(path: Path, archive: zipfile.ZipFile, name: str, expected: int | None, limit: int) -> bytes:
    """A zip member, read only if its declared size is the expected one (or within ``limit``)."""
    try:
        info = archive.getinfo(name)
    except KeyError:
        raise DesignError(f"{path}: the .x3p archive has no {name!r}") from None
    if expected is not None and info.file_size != expected:
        raise DesignError(
            f"{path}: .x3p member {name!r} holds {info.file_size:,} bytes; its header promises {expected:,}"
        )
    if info.file_size > limit:
        raise DesignError(
            f"{path}: .x3p member {name!r} unpacks to {info.file_size:,} bytes; expected a smaller file"
        )
    try:
        with archive.open(info) as member:
            data = member.read(info.file_size + 1)
    except Exception as exc:  # zipfile passes on zlib, bz2, lzma and encryption errors of its own kinds
        raise DesignError(
            f"{path}: cannot unpack .x3p member {name!r} ({type(exc).__name__}: {exc})"
        ) from None
    if len(data) != info.file_size:
        raise DesignError(f"{path}: .x3p member {name!r} does not unpack to its declared size")
    return data


def _read_x3p(path: Path) -> Topography:
    regular_file(path, "height map")
    try:
        archive = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError, ValueError) as exc:
        raise DesignError(f"{path}: not an .x3p file (expected a zip archive: {exc})") from None
    with archive:
        try:
            root = ElementTree.fromstring(_member(path, archive, "main.xml", None, 1 << 20))
        except ElementTree.ParseError as exc:
            raise DesignError(f"{path}: .x3p main.xml is not readable XML ({exc})") from None
        if _xml_text(path, root, "Record1", "FeatureType") != "SUR":
            raise DesignError(f"{path}: only areal (SUR) .x3p surfaces are supported")
        try:
            nx = int(_xml_text(path, root, "MatrixDimension", "SizeX"))
            ny = int(_xml_text(path, root, "MatrixDimension", "SizeY"))
            dx_m = float(_xml_text(path, root, "CX", "Increment"))
            dy_m = float(_xml_text(path, root, "CY", "Increment"))
        except ValueError as exc:
            raise DesignError(f"{path}: .x3p main.xml has an unreadable size or increment ({exc})") from None
        _check_grid(path, nx, ny, ".x3p")
        _check_pitch(path, dx_m, "CX/Increment")
        _check_pitch(path, dy_m, "CY/Increment")
        data_type = _xml_text(path, root, "CZ", "DataType")
        dtype = {"D": "<f8", "F": "<f4", "L": "<i4", "I": "<i2"}.get(data_type)
        if dtype is None:
            raise DesignError(f"{path}: .x3p data type {data_type!r}; expected D, F, L or I")
        link = _xml_text(path, root, "DataLink", "PointDataLink")
        size = nx * ny * np.dtype(dtype).itemsize
        data = np.frombuffer(_member(path, archive, link, size, size), dtype=dtype)
        heights = data.astype(np.float64).reshape(ny, nx)  # x index fastest
        if dtype[1] == "i":
            try:
                z_increment = float(_xml_text(path, root, "CZ", "Increment"))
            except DesignError:
                z_increment = 1.0
            except ValueError:
                raise DesignError(f"{path}: .x3p CZ/Increment is not a number") from None
            if not (math.isfinite(z_increment) and z_increment > 0):
                raise DesignError(f"{path}: .x3p CZ/Increment is {z_increment!r}; expected a positive number")
            heights *= z_increment
    return Topography(heights * 1000.0, dx_m * 1000.0, dy_m * 1000.0)


def _read_gwy(path: Path) -> Topography:
    import re

    import gwyfile
    from gwyfile.objects import GwyDataField

    data = read_bytes(path, "height map", max(1 << 20, budget_bytes() // 4))
    try:
        obj = gwyfile.load(io.BytesIO(data))
    except Exception as exc:  # gwyfile raises plain exceptions for malformed files
        raise DesignError(f"{path}: cannot read the Gwyddion file ({type(exc).__name__}: {exc})") from None
    # Channels are stored as /N/data; the first one is the height map.
    channels = sorted(
        (int(m.group(1)), value)
        for key, value in obj.items()
        if (m := re.fullmatch(r"/(\d+)/data", key)) and isinstance(value, GwyDataField)
    )
    if not channels:
        raise DesignError(f"{path}: the Gwyddion file holds no data field")
    field = channels[0][1]
    try:
        values = np.asarray(field.data, dtype=np.float64)
        xreal, yreal = float(field["xreal"]), float(field["yreal"])
    except (KeyError, TypeError, ValueError) as exc:
        raise DesignError(f"{path}: the Gwyddion data field is malformed ({exc})") from None
    if values.ndim != 2:
        raise DesignError(f"{path}: the Gwyddion data field is not a 2-D map")
    ny, nx = values.shape
    _check_grid(path, nx, ny, "the Gwyddion file")
    unit = field.get("si_unit_xy")
    in_metres = unit is None or unit.get("unitstr", "m") in ("m", "")
    scale = 1000.0 if in_metres else 1.0
    _check_pitch(path, xreal / nx / (1.0 if in_metres else 1000.0), "xreal / xres")
    _check_pitch(path, yreal / ny / (1.0 if in_metres else 1000.0), "yreal / yres")
    return Topography(values * scale, xreal / nx * scale, yreal / ny * scale)


def _read_npy(path: Path, pitch_mm: float | None) -> Topography:
    if pitch_mm is None:
        raise DesignError(f"{path}: a .npy height map needs --pitch-mm (its values are heights in mm)")
    regular_file(path, "height map")
    try:
        with open(path, "rb") as handle:
            version = np.lib.format.read_magic(handle)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(handle, max_header_size=1 << 16)
            else:
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(handle, max_header_size=1 << 16)
            start = handle.tell()
            handle.seek(0, io.SEEK_END)
            payload = handle.tell() - start
    except Exception as exc:  # numpy's header parser raises ValueError, SyntaxError, TokenError...
        raise DesignError(f"{path}: not a readable .npy file ({type(exc).__name__}: {exc})") from None
    if dtype.kind not in "fiub" or dtype.fields is not None or dtype.subdtype is not None:
        raise DesignError(f"{path}: the .npy holds {dtype} values; expected numbers (heights in mm)")
    if len(shape) != 2:
        raise DesignError(f"{path}: expected a 2-D array of heights, got shape {tuple(shape)}")
    _check_grid(path, int(shape[1]), int(shape[0]), "the .npy header")
    if payload < int(np.prod(shape)) * dtype.itemsize:
        raise DesignError(f"{path}: the .npy file is shorter than its header's {shape} {dtype} array")
    try:
        heights = np.load(path, allow_pickle=False)
    except (ValueError, OSError) as exc:
        raise DesignError(f"{path}: cannot read the .npy file ({exc})") from None
    return Topography(heights.astype(np.float64), pitch_mm, pitch_mm)


def _read_image(
    path: Path, width_mm: float | None, depth_mm: float | None, height_mm: float | None
) -> Topography:
    if width_mm is None or depth_mm is None:
        raise DesignError(
            f"{path}: an image has no physical scale; "
            "give --width-mm (its width) and --depth-mm (white minus black)"
        )
    image = open_image(path, "height map")
    with image:
        width, height = image.size
        if width < 2 or height < 2:
            raise DesignError(f"{path}: the image is {width} x {height} px; expected at least 2 x 2")
        mode = image.mode
        if mode in ("P", "PA", "LA", "RGBA", "CMYK", "YCbCr", "LAB", "HSV", "1"):
            image = image.convert("RGB" if mode not in ("1", "LA") else "L")
        values = np.asarray(image)
    if values.ndim == 3:
        values = values[..., :3].astype(np.float64).mean(axis=2)
        top = 255.0
    elif mode in ("I;16", "I;16B", "I;16L", "I") or values.dtype == np.uint16:
        top = 65535.0
    elif values.dtype == np.uint8:
        top = 255.0
    else:
        top = None  # floating-point TIFF: heights as they are, scaled by depth over their range
    values = values.astype(np.float64)
    if top is None:
        finite = values[np.isfinite(values)]
        if finite.size == 0:
            raise DesignError(f"{path}: every pixel of the floating-point image is NaN or infinite")
        span = float(finite.max() - finite.min()) or 1.0
        unit = np.where(np.isfinite(values), (values - finite.min()) / span, np.nan)
    else:
        unit = values / top
    rows, cols = unit.shape
    pitch_x = width_mm / (cols - 1)
    pitch_y = (height_mm / (rows - 1)) if height_mm is not None else pitch_x
    # Image row 0 is the far edge seen from above: flip so that row 0 is y = 0.
    return Topography(unit[::-1] * depth_mm, pitch_x, pitch_y)


def read_heightmap(
    path: str | Path,
    *,
    width_mm: float | None = None,
    depth_mm: float | None = None,
    length_mm: float | None = None,
    pitch_mm: float | None = None,
) -> Topography:
    """Read a height map with its physical scale.

    Parameters
    ----------
    path : path
        ``.png``, ``.tif``/``.tiff``, ``.npy``, ``.al3d``, ``.x3p`` or ``.gwy``.
    width_mm, depth_mm : float, optional
        Images only: physical width (x extent) and depth (height of white over black),
        the talk's "physical width" and "physical depth".
    length_mm : float, optional
        Images only: physical y extent, when the pixels are not square.
    pitch_mm : float, optional
        ``.npy`` only: sample spacing (its values are heights in mm).

    Raises
    ------
    DesignError
        Missing, special or unreadable files, unsupported formats, missing scale,
        inconsistent or out-of-range headers, maps larger than the memory budget.
    """
    path = regular_file(path, "height map")
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise DesignError(f"{path}: unsupported height map format; expected one of {', '.join(SUFFIXES)}")
    for name, value in (("--width-mm", width_mm), ("--depth-mm", depth_mm), ("--pitch-mm", pitch_mm)):
        if value is not None and not (math.isfinite(value) and 0 < value <= 1e6):
            raise DesignError(f"{name}: expected a positive, finite number (mm), got {value}")
    if suffix in IMAGE_SUFFIXES:
        topo = _read_image(path, width_mm, depth_mm, length_mm)
    elif suffix == ".npy":
        topo = _read_npy(path, pitch_mm)
    elif suffix == ".al3d":
        topo = _read_al3d(path)
    elif suffix == ".x3p":
        topo = _read_x3p(path)
    else:
        topo = _read_gwy(path)
    if min(topo.heights_mm.shape) < 2:
        raise DesignError(f"{path}: expected at least 2 x 2 samples, got {topo.heights_mm.shape}")
    finite = np.isfinite(topo.heights_mm)
    if not np.any(finite):
        raise DesignError(f"{path}: every sample is missing (NaN)")
    if np.any(np.isinf(topo.heights_mm)):
        raise DesignError(
            f"{path}: the map holds infinite heights; expected finite values or NaN for missing"
        )
    return topo
